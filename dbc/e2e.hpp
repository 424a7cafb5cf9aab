// End-to-end protection shared by every markloop message (AUTOSAR E2E
// profile 1-like): a 4-bit alive counter and a CRC-8 SAE J1850.
//
// CRC input, in this exact order (the DBC's global comment says the same):
//   1. low byte of the message's 16-bit data id (DBC attribute E2EDataID),
//   2. high byte of the data id,
//   3. every payload byte in increasing index, skipping the CRC byte.
// The data id is never sent; it makes a frame that arrives on the wrong CAN id
// (or from a mis-configured sender) fail the CRC.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include "dbc/crc8.hpp"

namespace markloop::dbc {

inline constexpr std::uint8_t kAliveCounterModulo = 16;

enum class DecodeError : std::uint8_t {
  None,         // valid: the output was written
  WrongLength,  // payload length differs from the message's DLC
  BadCrc,       // CRC mismatch (corrupted, or wrong data id / CAN id)
  BadCounter,   // alive counter repeated or skipped (see E2eReceiverState)
  OutOfRange,   // a raw value outside the DBC's [min|max] or value table
  UnknownPage,  // multiplexor value that the DBC does not define
};

constexpr std::string_view to_string(DecodeError error) noexcept {
  switch (error) {
    case DecodeError::None:
      return "None";
    case DecodeError::WrongLength:
      return "WrongLength";
    case DecodeError::BadCrc:
      return "BadCrc";
    case DecodeError::BadCounter:
      return "BadCounter";
    case DecodeError::OutOfRange:
      return "OutOfRange";
    case DecodeError::UnknownPage:
      return "UnknownPage";
  }
  return "?";
}

constexpr std::uint8_t e2e_crc(std::uint16_t data_id, std::span<const std::uint8_t> payload,
                               std::size_t crc_byte) noexcept {
  Crc8J1850 crc;
  crc.add(static_cast<std::uint8_t>(data_id & 0xFFU));
  crc.add(static_cast<std::uint8_t>(data_id >> 8));
  for (std::size_t i = 0; i < payload.size(); ++i) {
    if (i != crc_byte) crc.add(payload[i]);
  }
  return crc.value();
}

// Sender side: one per CAN id. Every frame sent on the id takes the next value
// (pages of a multiplexed message included), 15 wraps to 0.
class E2eSenderState {
 public:
  constexpr std::uint8_t next() noexcept {
    const std::uint8_t value = counter_;
    counter_ = static_cast<std::uint8_t>((counter_ + 1U) % kAliveCounterModulo);
    return value;
  }

 private:
  std::uint8_t counter_ = 0;
};

// Receiver side: one per CAN id. Policy:
//  - the first frame after construction or reset() is accepted whatever its
//    counter (we cannot know where the sender is after our start or after a
//    receive timeout; Receiver<> resets on timeout), and synchronises;
//  - afterwards only last + 1 (mod 16) is accepted;
//  - a repeated counter (same value) is rejected and changes nothing, so a
//    stuck sender keeps failing;
//  - a skipped counter (frames lost) is rejected but resynchronises on the
//    received value, so the next in-sequence frame is accepted again.
class E2eReceiverState {
 public:
  constexpr void reset() noexcept { synchronised_ = false; }
  constexpr bool synchronised() const noexcept { return synchronised_; }
  constexpr std::uint8_t last_counter() const noexcept { return last_counter_; }

  // Returns true when `counter` is acceptable; updates the state as above.
  constexpr bool accept(std::uint8_t counter) noexcept {
    counter = static_cast<std::uint8_t>(counter % kAliveCounterModulo);
    if (!synchronised_) {
      synchronised_ = true;
      last_counter_ = counter;
      return true;
    }
    const auto delta =
        static_cast<std::uint8_t>((counter + kAliveCounterModulo - last_counter_) % kAliveCounterModulo);
    if (delta == 0) return false;  // repeated
    last_counter_ = counter;
    return delta == 1;  // else skipped: resynchronised but rejected
  }

 private:
  bool synchronised_ = false;
  std::uint8_t last_counter_ = 0;
};

}  // namespace markloop::dbc
