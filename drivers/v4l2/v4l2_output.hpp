// V4L2 video output node (e.g. vivid's output, which vivid can loop back
// into its capture node): the simulator's live mode writes frames here and
// the camera reads them back through real V4L2 streaming.
//
// States: Closed --open() ok--> Opened --start() ok--> Streaming;
//         any --stop()--> Closed (safe any number of times).
// Frames go out through mmap buffers without an extra copy: acquire() hands
// out a free buffer (one never queued, or one the driver has finished
// with), the caller fills it, submit() queues it. send_luma() does the three
// steps for a packed 8-bit image (YUYV gets neutral chroma).
// A driver error during streaming is returned to the caller and counted;
// the output does not reopen by itself (its user restarts it).
//
// Rules as V4l2Camera: no exceptions, no heap, every ioctl through
// V4l2Device, counters instead of logging.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <span>
#include <string_view>
#include <system_error>

#include "drivers/v4l2/v4l2_device.hpp"
#include "drivers/v4l2/v4l2_format.hpp"

namespace markloop::v4l2 {

struct OutputConfig {
  std::string_view device = "/dev/video1";
  int output = -1;  // VIDIOC_S_OUTPUT index; -1 keeps the current one
  std::uint32_t width = 640;
  std::uint32_t height = 480;
  PixelFormat format = PixelFormat::Grey;
  std::uint32_t fps = 0;  // 0 keeps the driver's rate
  std::uint32_t buffer_count = 4;
};

struct OutputBuffer {
  std::uint8_t* data = nullptr;
  std::uint32_t capacity = 0;  // mapped bytes
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::uint32_t stride = 0;
  std::uint32_t image_size = 0;
  PixelFormat format = PixelFormat::Grey;
  std::uint32_t index = 0;
  std::uint32_t generation = 0;
};

struct OutputCounters {
  std::uint64_t frames_queued = 0;
  std::uint64_t frames_done = 0;    // returned by the driver
  std::uint64_t buffer_errors = 0;  // returned with V4L2_BUF_FLAG_ERROR
  std::uint64_t timeouts = 0;       // acquire() found no free buffer in time
  std::uint64_t io_errors = 0;
};

class V4l2Output {
 public:
  enum class State { Closed, Opened, Streaming };
  static constexpr std::size_t kMaxPath = 128;

  V4l2Output() = default;
  ~V4l2Output() { stop(); }
  V4l2Output(const V4l2Output&) = delete;
  V4l2Output& operator=(const V4l2Output&) = delete;

  std::error_code open(const OutputConfig& config) noexcept;
  std::error_code start() noexcept;  // Opened -> Streaming (STREAMON)
  std::error_code start(const OutputConfig& config) noexcept;
  void stop() noexcept;

  // A buffer to fill, within `timeout`: timed_out when the driver holds all.
  std::error_code acquire(OutputBuffer& out, std::chrono::milliseconds timeout) noexcept;
  // Queues an acquired buffer with `bytes_used` bytes (normally image_size).
  std::error_code submit(const OutputBuffer& buffer, std::uint32_t bytes_used) noexcept;
  // acquire + fill_from_luma + submit. `luma` is width*height bytes.
  std::error_code send_luma(std::span<const std::uint8_t> luma, std::chrono::milliseconds timeout) noexcept;

  State state() const noexcept { return state_; }
  const OutputCounters& counters() const noexcept { return counters_; }
  const DeviceInfo& device_info() const noexcept { return info_; }
  const NegotiatedFormat& format() const noexcept { return format_; }
  const FrameInterval& frame_interval() const noexcept { return interval_; }
  std::size_t buffer_count() const noexcept { return device_.buffer_count(); }
  V4l2Device& device() noexcept { return device_; }

  static std::error_code validate(const OutputConfig& config) noexcept;

 private:
  enum class Slot : std::uint8_t { Free, Acquired, Queued };

  V4l2Device device_;
  State state_ = State::Closed;
  std::array<char, kMaxPath> path_{};
  DeviceInfo info_{};
  NegotiatedFormat format_{};
  FrameInterval interval_{};
  std::array<Slot, V4l2Device::kMaxBuffers> slots_{};
  std::uint32_t generation_ = 1;  // views default to 0: never current
  OutputCounters counters_{};
};

const char* to_string(V4l2Output::State state) noexcept;

}  // namespace markloop::v4l2
