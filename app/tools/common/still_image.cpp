#include "app/tools/common/still_image.hpp"

#include <algorithm>
#include <array>
#include <cstring>
#include <string>
#include <system_error>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "app/tools/common/tool_files.hpp"
#include "platform/files.hpp"

namespace markloop::io {
namespace {

constexpr std::array<std::uint8_t, 8> kPngSignature = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
constexpr std::uint8_t kJpegMarker = 0xff;
constexpr std::uint8_t kJpegStartOfImage = 0xd8;
constexpr std::uint8_t kJpegStartOfScan = 0xda;
constexpr std::uint8_t kJpegEndOfImage = 0xd9;
// Larger than any still a camera of this product takes (an 8-bit 4K frame
// is 8 MB before compression): a bigger file is refused before it is read.
constexpr std::size_t kMaxStillBytes = std::size_t{256} << 20;

std::uint32_t big_endian_u32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) | p[3];
}

std::uint32_t big_endian_u16(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 8) | p[1];
}

bool is_png(std::span<const std::uint8_t> bytes) {
  return bytes.size() >= kPngSignature.size() &&
         std::equal(kPngSignature.begin(), kPngSignature.end(), bytes.begin());
}

bool is_jpeg(std::span<const std::uint8_t> bytes) {
  return bytes.size() >= 3 && bytes[0] == kJpegMarker && bytes[1] == kJpegStartOfImage &&
         bytes[2] == kJpegMarker;
}

// Walks the chunks (length, type, data, CRC) up to IEND; every length is
// checked against the bytes left.
bool png_is_complete(std::span<const std::uint8_t> bytes) {
  std::size_t at = kPngSignature.size();
  while (bytes.size() - at >= 12) {
    const std::uint32_t length = big_endian_u32(&bytes[at]);
    if (length > bytes.size() - at - 12) return false;
    if (std::memcmp(&bytes[at + 4], "IEND", 4) == 0) return true;
    at += 12 + std::size_t{length};
  }
  return false;
}

// In a JPEG's entropy-coded data 0xff is always followed by 0x00 or a
// restart marker, so a start-of-scan or end-of-image marker can only be a
// marker. An end-of-image before the last scan belongs to a thumbnail (EXIF).
bool jpeg_is_complete(std::span<const std::uint8_t> bytes) {
  std::size_t last_scan = 0, last_end = 0;
  for (std::size_t i = 2; i + 1 < bytes.size(); ++i) {
    if (bytes[i] != kJpegMarker) continue;
    if (bytes[i + 1] == kJpegStartOfScan) last_scan = i;
    if (bytes[i + 1] == kJpegEndOfImage) last_end = i;
  }
  return last_scan != 0 && last_end > last_scan;
}

// The IHDR chunk, which must come first: width and height, each at most
// 2^31 - 1 by the PNG specification.
cv::Size png_size(std::span<const std::uint8_t> bytes) {
  const std::size_t at = kPngSignature.size();
  if (bytes.size() < at + 16 || big_endian_u32(&bytes[at]) != 13 ||
      std::memcmp(&bytes[at + 4], "IHDR", 4) != 0)
    return {};
  const std::uint32_t width = big_endian_u32(&bytes[at + 8]), height = big_endian_u32(&bytes[at + 12]);
  if (width == 0 || height == 0 || width > 0x7fffffffu || height > 0x7fffffffu) return {};
  return {static_cast<int>(width), static_cast<int>(height)};
}

// The segments before the first scan, each length checked against the
// bytes left, up to the frame header (SOF0..SOF15 but DHT, JPG and DAC,
// which share the range): precision, height, width. An EXIF thumbnail's
// frame header lies inside its APP1 segment, which is skipped whole. A
// height of 0 (given later by a DNL segment) is not trusted.
cv::Size jpeg_size(std::span<const std::uint8_t> bytes) {
  constexpr std::uint8_t kDefineHuffman = 0xc4, kExtension = 0xc8, kDefineArithmetic = 0xcc;
  std::size_t at = 2;
  while (at + 4 <= bytes.size()) {
    if (bytes[at] != kJpegMarker) return {};
    const std::uint8_t code = bytes[at + 1];
    if (code == kJpegMarker) {  // a fill byte before the marker
      ++at;
      continue;
    }
    if (code == 0x01 || (code >= 0xd0 && code <= 0xd7)) {  // markers without a length
      at += 2;
      continue;
    }
    if (code == kJpegStartOfScan || code == kJpegEndOfImage) return {};
    const std::size_t length = big_endian_u16(&bytes[at + 2]);
    if (length < 2 || length > bytes.size() - at - 2) return {};
    if (code >= 0xc0 && code <= 0xcf && code != kDefineHuffman && code != kExtension &&
        code != kDefineArithmetic) {
      if (length < 8) return {};
      const std::uint32_t height = big_endian_u16(&bytes[at + 5]), width = big_endian_u16(&bytes[at + 7]);
      if (width == 0 || height == 0) return {};
      return {static_cast<int>(width), static_cast<int>(height)};
    }
    at += 2 + length;
  }
  return {};
}

}  // namespace

StillCheck check_still(std::span<const std::uint8_t> bytes) {
  if (is_png(bytes)) return png_is_complete(bytes) ? StillCheck::kComplete : StillCheck::kTruncatedPng;
  if (is_jpeg(bytes)) return jpeg_is_complete(bytes) ? StillCheck::kComplete : StillCheck::kTruncatedJpeg;
  return StillCheck::kUnknownFormat;
}

cv::Size declared_still_size(std::span<const std::uint8_t> bytes) {
  if (is_png(bytes)) return png_size(bytes);
  if (is_jpeg(bytes)) return jpeg_size(bytes);
  return {};
}

Result<cv::Mat> read_grey_still(const std::string& path, cv::Size camera_size) {
  std::string file;
  if (const std::error_code ec = platform::read_file_bounded(path.c_str(), kMaxStillBytes, file)) {
    if (ec == std::errc::is_a_directory) return error("is a directory, not an image");
    if (ec == std::errc::file_too_large) return error("larger than 256 MiB, the limit for an image");
    return error("cannot open: " + ec.message());
  }
  const std::span<const std::uint8_t> bytes(reinterpret_cast<const std::uint8_t*>(file.data()), file.size());
  switch (check_still(bytes)) {
    case StillCheck::kComplete:
      break;
    case StillCheck::kUnknownFormat:
      return error("cannot read as an image (PNG or JPEG)");
    case StillCheck::kTruncatedPng:
      return error("truncated PNG (it ends before its IEND chunk)");
    case StillCheck::kTruncatedJpeg:
      return error("truncated JPEG (no end-of-image marker after its image data)");
  }
  const cv::Size declared = declared_still_size(bytes);
  if (declared.empty()) {
    return error("corrupt PNG or JPEG (no image size in its header)");
  }
  if (declared != camera_size) {
    return error("image is " + std::to_string(declared.width) + "x" + std::to_string(declared.height) +
                 ", the camera's " + std::to_string(camera_size.width) + "x" +
                 std::to_string(camera_size.height));
  }
  cv::Mat grey;
  try {
    // The pixels as the camera stored them: an EXIF orientation would turn
    // the image away from the calibration (and from the header's size).
    const cv::Mat encoded(1, static_cast<int>(file.size()), CV_8UC1, file.data());
    grey = cv::imdecode(encoded, cv::IMREAD_GRAYSCALE | cv::IMREAD_IGNORE_ORIENTATION);
  } catch (const cv::Exception&) {
    grey.release();
  }
  // A decoder that disagrees with the header is not trusted either.
  if (grey.empty() || grey.size() != declared) {
    return error("corrupt PNG or JPEG (cannot decode it)");
  }
  return grey;
}

Status write_png(const std::string& path, const cv::Mat& image) {
  std::vector<std::uint8_t> png;
  try {
    if (!cv::imencode(".png", image, png)) png.clear();
  } catch (const cv::Exception& e) {
    return error(path + ": cannot encode the PNG: " + e.what());
  }
  if (png.empty()) {
    return error(path + ": cannot encode the PNG");
  }
  return tools::write_whole_file(path, png.data(), png.size());
}

}  // namespace markloop::io
