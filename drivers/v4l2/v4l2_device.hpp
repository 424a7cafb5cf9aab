// One open V4L2 video node with its mmap buffers: the only code that issues
// V4L2 ioctls (through platform::sys_ioctl: EINTR retried, errors as
// std::error_code). V4l2Camera and V4l2Output are state machines on top.
//
// Every reply of the driver is checked: pixel format and size as asked,
// bytesperline/sizeimage consistent, buffer count exactly as requested,
// buffer lengths at least the image size, dequeued indexes in range.
#pragma once

#include <linux/videodev2.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <system_error>

#include "drivers/v4l2/v4l2_format.hpp"
#include "platform/unique_fd.hpp"

namespace markloop::v4l2 {

struct DeviceInfo {
  std::array<char, 16> driver{};
  std::array<char, 32> card{};
  std::array<char, 32> bus{};
  std::uint32_t capabilities = 0;  // device_caps when the driver reports them
};

struct NegotiatedFormat {
  PixelFormat format = PixelFormat::Grey;
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::uint32_t stride = 0;      // bytes per row
  std::uint32_t image_size = 0;  // bytes per image
};

// Frame interval granted by the driver (0/0 when it does not say).
struct FrameInterval {
  std::uint32_t numerator = 0;
  std::uint32_t denominator = 0;
  bool settable = false;  // driver has V4L2_CAP_TIMEPERFRAME
};

struct MappedBuffer {
  std::uint8_t* data = nullptr;
  std::size_t length = 0;
};

class V4l2Device {
 public:
  // Above V4L2's own limit (VIDEO_MAX_FRAME = 32), so that a driver which
  // clamps a request shows up as TooFewBuffers, not as our own refusal.
  static constexpr std::size_t kMaxBuffers = 64;

  enum class Direction { Capture, Output };

  V4l2Device() = default;
  ~V4l2Device() { close(); }
  V4l2Device(const V4l2Device&) = delete;
  V4l2Device& operator=(const V4l2Device&) = delete;
  V4l2Device(V4l2Device&&) = delete;
  V4l2Device& operator=(V4l2Device&&) = delete;

  // Opens `path` non-blocking and checks it is a streaming capture/output
  // node (QUERYCAP). A regular file fails with ENOTTY, a missing node with
  // ENOENT.
  std::error_code open(const char* path, Direction direction, DeviceInfo& info) noexcept;
  // Stops streaming, unmaps, frees the driver's buffers, closes. Idempotent.
  void close() noexcept;
  bool is_open() const noexcept { return fd_.valid(); }
  int fd() const noexcept { return fd_.get(); }

  std::error_code select_input(int index) noexcept;   // VIDIOC_S_INPUT
  std::error_code select_output(int index) noexcept;  // VIDIOC_S_OUTPUT
  std::error_code set_format(std::uint32_t width, std::uint32_t height, PixelFormat format,
                             NegotiatedFormat& out) noexcept;
  // fps 0 only reads the current interval.
  std::error_code set_frame_rate(std::uint32_t fps, FrameInterval& out) noexcept;
  // REQBUFS exactly `count` MMAP buffers, QUERYBUF and map each; each must
  // hold at least `image_size` bytes. Fails (and frees them) otherwise.
  std::error_code request_buffers(std::uint32_t count, std::uint32_t image_size) noexcept;
  std::size_t buffer_count() const noexcept { return buffer_count_; }
  const MappedBuffer& buffer(std::size_t index) const noexcept { return buffers_[index]; }

  std::error_code queue(std::uint32_t index, std::uint32_t bytes_used) noexcept;
  // DQBUF (non-blocking): EAGAIN when nothing is done yet. The index is
  // checked against the buffer table before returning.
  std::error_code dequeue(v4l2_buffer& out) noexcept;
  std::error_code stream_on() noexcept;
  std::error_code stream_off() noexcept;
  bool streaming() const noexcept { return streaming_; }

  std::error_code set_control(std::uint32_t id, std::int32_t value) noexcept;
  std::error_code get_control(std::uint32_t id, std::int32_t& value) noexcept;

  // The single ioctl entry point of the V4L2 drivers.
  std::error_code ioctl(unsigned long request, void* arg) noexcept;

 private:
  std::uint32_t buffer_type() const noexcept {
    return direction_ == Direction::Capture ? V4L2_BUF_TYPE_VIDEO_CAPTURE : V4L2_BUF_TYPE_VIDEO_OUTPUT;
  }
  void unmap_and_free() noexcept;

  platform::UniqueFd fd_;
  Direction direction_ = Direction::Capture;
  std::array<MappedBuffer, kMaxBuffers> buffers_{};
  std::size_t buffer_count_ = 0;
  bool buffers_requested_ = false;
  bool streaming_ = false;
};

}  // namespace markloop::v4l2
