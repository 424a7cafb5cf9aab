// Device-independent pieces of the V4L2 drivers: pixel formats and fourcc
// codes, the driver's own error codes, sequence-gap accounting and luma
// extraction. Pure functions, no kernel calls: unit-tested on the host.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <system_error>

namespace markloop::v4l2 {

// The formats markloop captures and outputs: 8-bit grey, and YUYV 4:2:2 for
// devices without grey (the luma is every other byte).
enum class PixelFormat : std::uint8_t { Grey, Yuyv };

constexpr std::uint32_t make_fourcc(char a, char b, char c, char d) noexcept {
  return static_cast<std::uint32_t>(static_cast<unsigned char>(a)) |
         static_cast<std::uint32_t>(static_cast<unsigned char>(b)) << 8 |
         static_cast<std::uint32_t>(static_cast<unsigned char>(c)) << 16 |
         static_cast<std::uint32_t>(static_cast<unsigned char>(d)) << 24;
}

std::uint32_t to_fourcc(PixelFormat format) noexcept;
std::optional<PixelFormat> from_fourcc(std::uint32_t fourcc) noexcept;
// Bytes per pixel in the (single) plane.
std::uint32_t bytes_per_pixel(PixelFormat format) noexcept;
const char* to_string(PixelFormat format) noexcept;
// "GREY", "YUYV", ...; non-printable bytes become '?'. Always NUL-terminated.
std::array<char, 5> fourcc_string(std::uint32_t fourcc) noexcept;

// Errors the drivers detect themselves (the kernel's own errors are passed on
// as system_category errno values).
enum class V4l2Error {
  NotACaptureDevice = 1,  // no V4L2_CAP_VIDEO_CAPTURE
  NotAnOutputDevice,      // no V4L2_CAP_VIDEO_OUTPUT
  NoStreaming,            // no V4L2_CAP_STREAMING (mmap I/O)
  FormatRefused,          // the driver answered S_FMT with another pixel format
  SizeRefused,            // ... or another width/height
  BadFormatReply,         // bytesperline/sizeimage inconsistent with the size
  FrameRateRefused,       // the driver answered S_PARM with another rate
  TooFewBuffers,          // REQBUFS granted fewer buffers than requested
  TooManyBuffers,         // ... or more than the driver can track
  BufferTooSmall,         // a buffer is smaller than the image
  BuffersExhausted,       // every buffer is held by the caller
  StaleFrame,             // release() of a view from before a restart
  NotStreaming,           // the call needs a streaming device
  Recovering,             // device lost; reopening with back-off
};
const std::error_category& v4l2_category() noexcept;
inline std::error_code make_error_code(V4l2Error e) noexcept {
  return {static_cast<int>(e), v4l2_category()};
}

// Frames lost between driver sequence numbers. V4L2 numbers every frame the
// device produced (dropped ones included) from 0 after STREAMON, modulo 2^32.
class SequenceTracker {
 public:
  struct Step {
    std::uint32_t missed = 0;  // frames skipped before this one
    bool restarted = false;    // sequence went backwards or repeated
  };
  // Records `sequence` and says how many were missed since the previous one.
  // A backwards jump (driver restart) or a repeat is not counted as a loss.
  Step update(std::uint32_t sequence) noexcept;
  void reset() noexcept { has_last_ = false; }
  bool has_last() const noexcept { return has_last_; }
  std::uint32_t last() const noexcept { return last_; }

 private:
  std::uint32_t last_ = 0;
  bool has_last_ = false;
};

// Copies the luma of one image into `out` (width*height bytes, packed).
// `image` is `stride` bytes per row; GREY rows are copied, YUYV's every other
// byte is taken. Returns false (and writes nothing) when a size is wrong.
bool extract_luma(PixelFormat format, std::span<const std::uint8_t> image, std::uint32_t width,
                  std::uint32_t height, std::uint32_t stride, std::span<std::uint8_t> out) noexcept;

// The inverse for output devices: writes packed luma (width*height) as one
// image of `format` (YUYV gets neutral chroma 128). False when sizes are wrong.
bool fill_from_luma(PixelFormat format, std::span<const std::uint8_t> luma, std::uint32_t width,
                    std::uint32_t height, std::uint32_t stride, std::span<std::uint8_t> image) noexcept;

}  // namespace markloop::v4l2

template <>
struct std::is_error_code_enum<markloop::v4l2::V4l2Error> : std::true_type {};
