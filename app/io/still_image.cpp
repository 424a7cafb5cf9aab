#include "io/still_image.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <vector>

#include <opencv2/imgcodecs.hpp>

namespace markloop::io {
namespace {

constexpr std::array<std::uint8_t, 8> kPngSignature = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
constexpr std::uint8_t kJpegMarker = 0xff;
constexpr std::uint8_t kJpegStartOfImage = 0xd8;
constexpr std::uint8_t kJpegStartOfScan = 0xda;
constexpr std::uint8_t kJpegEndOfImage = 0xd9;
// Larger than any still a camera of this product takes (an 8-bit 4K frame
// is 8 MB before compression): a bigger file is refused before it is read.
constexpr std::uintmax_t kMaxStillBytes = 256u << 20;

std::uint32_t big_endian_u32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) | p[3];
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

}  // namespace

StillCheck check_still(std::span<const std::uint8_t> bytes) {
  if (bytes.size() >= kPngSignature.size() &&
      std::equal(kPngSignature.begin(), kPngSignature.end(), bytes.begin()))
    return png_is_complete(bytes) ? StillCheck::kComplete : StillCheck::kTruncatedPng;
  if (bytes.size() >= 3 && bytes[0] == kJpegMarker && bytes[1] == kJpegStartOfImage &&
      bytes[2] == kJpegMarker)
    return jpeg_is_complete(bytes) ? StillCheck::kComplete : StillCheck::kTruncatedJpeg;
  return StillCheck::kUnknownFormat;
}

cv::Mat read_grey_still(const std::string& path, std::string& error) {
  errno = 0;
  std::ifstream file(path, std::ios::binary | std::ios::ate);
  if (!file) {
    error = errno != 0 ? std::string("cannot open: ") + std::strerror(errno) : "cannot open";
    return {};
  }
  const std::streamoff size = file.tellg();
  if (size < 0 || static_cast<std::uintmax_t>(size) > kMaxStillBytes) {
    error = size < 0 ? "cannot read its size" : "larger than 256 MB: not a still image";
    return {};
  }
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
  file.seekg(0);
  if (!file.read(reinterpret_cast<char*>(bytes.data()), size)) {
    error = "read error";
    return {};
  }
  switch (check_still(bytes)) {
    case StillCheck::kComplete:
      break;
    case StillCheck::kUnknownFormat:
      error = "cannot read as an image (PNG or JPEG)";
      return {};
    case StillCheck::kTruncatedPng:
      error = "truncated PNG (it ends before its IEND chunk)";
      return {};
    case StillCheck::kTruncatedJpeg:
      error = "truncated JPEG (no end-of-image marker after its image data)";
      return {};
  }
  cv::Mat grey;
  try {
    grey = cv::imdecode(bytes, cv::IMREAD_GRAYSCALE);
  } catch (const cv::Exception&) {
    grey.release();
  }
  if (grey.empty()) error = "corrupt PNG or JPEG (cannot decode it)";
  return grey;
}

}  // namespace markloop::io
