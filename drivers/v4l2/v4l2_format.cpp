#include "drivers/v4l2/v4l2_format.hpp"

#include <cstring>
#include <string>

namespace markloop::v4l2 {

std::uint32_t to_fourcc(PixelFormat format) noexcept {
  switch (format) {
    case PixelFormat::Grey:
      return make_fourcc('G', 'R', 'E', 'Y');
    case PixelFormat::Yuyv:
      return make_fourcc('Y', 'U', 'Y', 'V');
  }
  return 0;
}

std::optional<PixelFormat> from_fourcc(std::uint32_t fourcc) noexcept {
  if (fourcc == make_fourcc('G', 'R', 'E', 'Y')) return PixelFormat::Grey;
  if (fourcc == make_fourcc('Y', 'U', 'Y', 'V')) return PixelFormat::Yuyv;
  return std::nullopt;
}

std::uint32_t bytes_per_pixel(PixelFormat format) noexcept {
  return format == PixelFormat::Yuyv ? 2U : 1U;
}

const char* to_string(PixelFormat format) noexcept {
  switch (format) {
    case PixelFormat::Grey:
      return "GREY";
    case PixelFormat::Yuyv:
      return "YUYV";
  }
  return "?";
}

std::array<char, 5> fourcc_string(std::uint32_t fourcc) noexcept {
  std::array<char, 5> s{};
  for (int i = 0; i < 4; ++i) {
    const auto c = static_cast<char>((fourcc >> (8 * i)) & 0xFFU);
    s[static_cast<std::size_t>(i)] = (c >= 0x20 && c < 0x7F) ? c : '?';
  }
  return s;
}

namespace {

class V4l2Category final : public std::error_category {
 public:
  const char* name() const noexcept override { return "v4l2"; }
  std::string message(int value) const override {
    switch (static_cast<V4l2Error>(value)) {
      case V4l2Error::NotACaptureDevice:
        return "not a video capture device";
      case V4l2Error::NotAnOutputDevice:
        return "not a video output device";
      case V4l2Error::NoStreaming:
        return "device does not support streaming I/O";
      case V4l2Error::FormatRefused:
        return "driver refused the pixel format";
      case V4l2Error::SizeRefused:
        return "driver refused the image size";
      case V4l2Error::BadFormatReply:
        return "driver reported an inconsistent format";
      case V4l2Error::FrameRateRefused:
        return "driver refused the frame rate";
      case V4l2Error::TooFewBuffers:
        return "driver granted fewer buffers than requested";
      case V4l2Error::TooManyBuffers:
        return "driver granted more buffers than supported";
      case V4l2Error::BufferTooSmall:
        return "driver buffer smaller than the image";
      case V4l2Error::BuffersExhausted:
        return "every buffer is held by the caller";
      case V4l2Error::StaleFrame:
        return "frame view is from before a restart";
      case V4l2Error::NotStreaming:
        return "device is not streaming";
      case V4l2Error::Recovering:
        return "device lost, recovering";
    }
    return "unknown v4l2 error";
  }
};

}  // namespace

const std::error_category& v4l2_category() noexcept {
  static const V4l2Category category;
  return category;
}

SequenceTracker::Step SequenceTracker::update(std::uint32_t sequence) noexcept {
  Step step;
  if (has_last_) {
    // Unsigned difference handles the 2^32 wrap; more than half the range
    // ahead means the sequence went backwards.
    const std::uint32_t ahead = sequence - last_;
    if (ahead == 0 || ahead > 0x8000'0000U)
      step.restarted = true;
    else
      step.missed = ahead - 1;
  }
  last_ = sequence;
  has_last_ = true;
  return step;
}

namespace {

bool sizes_ok(PixelFormat format, std::size_t image_size, std::uint32_t width, std::uint32_t height,
              std::uint32_t stride, std::size_t luma_size) noexcept {
  if (width == 0 || height == 0) return false;
  if (format == PixelFormat::Yuyv && width % 2 != 0) return false;
  const std::uint64_t row = static_cast<std::uint64_t>(width) * bytes_per_pixel(format);
  if (stride < row) return false;
  const std::uint64_t needed = static_cast<std::uint64_t>(stride) * (height - 1) + row;
  if (image_size < needed) return false;
  return luma_size == static_cast<std::uint64_t>(width) * height;
}

}  // namespace

bool extract_luma(PixelFormat format, std::span<const std::uint8_t> image, std::uint32_t width,
                  std::uint32_t height, std::uint32_t stride, std::span<std::uint8_t> out) noexcept {
  if (!sizes_ok(format, image.size(), width, height, stride, out.size())) return false;
  for (std::uint32_t y = 0; y < height; ++y) {
    const std::uint8_t* src = image.data() + static_cast<std::size_t>(y) * stride;
    std::uint8_t* dst = out.data() + static_cast<std::size_t>(y) * width;
    if (format == PixelFormat::Grey) {
      std::memcpy(dst, src, width);
    } else {
      for (std::uint32_t x = 0; x < width; ++x) dst[x] = src[2 * x];
    }
  }
  return true;
}

bool fill_from_luma(PixelFormat format, std::span<const std::uint8_t> luma, std::uint32_t width,
                    std::uint32_t height, std::uint32_t stride, std::span<std::uint8_t> image) noexcept {
  if (!sizes_ok(format, image.size(), width, height, stride, luma.size())) return false;
  for (std::uint32_t y = 0; y < height; ++y) {
    const std::uint8_t* src = luma.data() + static_cast<std::size_t>(y) * width;
    std::uint8_t* dst = image.data() + static_cast<std::size_t>(y) * stride;
    if (format == PixelFormat::Grey) {
      std::memcpy(dst, src, width);
    } else {
      for (std::uint32_t x = 0; x < width; ++x) {
        dst[2 * x] = src[x];
        dst[2 * x + 1] = 128;  // neutral chroma
      }
    }
  }
  return true;
}

}  // namespace markloop::v4l2
