// The frame type shared by every CAN sink and source in markloop, and the sink
// interface the application writes to (a SocketCAN socket or a candump log).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <system_error>

namespace markloop::can {

struct CanFrame {
  static constexpr std::uint32_t kMaxStandardId = 0x7FF;
  static constexpr std::uint32_t kMaxExtendedId = 0x1FFFFFFF;
  static constexpr std::uint8_t kMaxDlc = 8;

  std::uint32_t id = 0;  // 11-bit (standard) or 29-bit (extended), no flags
  bool extended = false;
  std::uint8_t dlc = 0;  // payload length 0..8
  std::array<std::uint8_t, 8> data{};
  std::int64_t timestamp_ns = 0;  // CLOCK_REALTIME; 0 = not known

  std::span<const std::uint8_t> payload() const { return {data.data(), dlc <= kMaxDlc ? dlc : kMaxDlc}; }
  // Id fits its format and dlc <= 8.
  bool valid() const { return dlc <= kMaxDlc && id <= (extended ? kMaxExtendedId : kMaxStandardId); }
};

// Same id, format, length and payload bytes (timestamps and bytes past dlc
// are ignored).
inline bool same_content(const CanFrame& a, const CanFrame& b) {
  if (a.id != b.id || a.extended != b.extended || a.dlc != b.dlc || a.dlc > CanFrame::kMaxDlc) return false;
  for (std::uint8_t i = 0; i < a.dlc; ++i)
    if (a.data[i] != b.data[i]) return false;
  return true;
}

// Where the application sends frames. send() never blocks and never throws;
// it returns {} when the frame was accepted (sent or queued for sending).
class CanFrameSink {
 public:
  virtual ~CanFrameSink() = default;
  virtual std::error_code send(const CanFrame& frame) noexcept = 0;
};

// One kernel receive filter: a frame passes when (frame.id & mask) == (id & mask)
// and its format (standard/extended) equals `extended`. Remote frames never pass.
struct CanFilter {
  std::uint32_t id = 0;
  std::uint32_t mask = CanFrame::kMaxExtendedId;
  bool extended = false;

  static constexpr CanFilter exact(std::uint32_t id, bool extended = false) {
    return {id, extended ? CanFrame::kMaxExtendedId : CanFrame::kMaxStandardId, extended};
  }
};

}  // namespace markloop::can
