// Still images (PNG or JPEG) read for the host tools: markloop-detect and
// markloop-train. Built with the tools only (it needs OpenCV's imgcodecs,
// which the ECU does not link).
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include <opencv2/core/mat.hpp>

#include "app/common/result.hpp"

namespace markloop::io {

enum class StillCheck : std::uint8_t {
  kComplete,
  kUnknownFormat,  // neither PNG's nor JPEG's signature
  kTruncatedPng,   // ends inside a chunk or before the IEND chunk
  kTruncatedJpeg,  // no end-of-image marker after the last scan
};

// Whether `bytes` hold a whole PNG or JPEG file, judged by its structure
// alone (no decoding). libjpeg decodes a truncated JPEG without failing and
// fills the missing rows with grey, which the detector would then search as
// road; so the tools refuse such a file instead.
StillCheck check_still(std::span<const std::uint8_t> bytes);

// The width and height a complete PNG or JPEG declares in its header (PNG:
// the IHDR chunk; JPEG: the frame header before the first scan), or an
// empty size when it declares none that can be trusted.
cv::Size declared_still_size(std::span<const std::uint8_t> bytes);

// Reads `path`, checks it with check_still(), compares the size its header
// declares with `camera_size` and only then decodes it to 8-bit grey: a
// small file may declare a huge image (a "decompression bomb"), which would
// otherwise be decoded into memory before the tool could refuse it.
// On failure the error says what was wrong (without the path: the caller
// adds it).
Result<cv::Mat> read_grey_still(const std::string& path, cv::Size camera_size);

// `image` as a PNG file, encoded in memory and then written whole and
// checked: else "PATH: why" (a full disk, where imwrite would only return
// false).
Status write_png(const std::string& path, const cv::Mat& image);

}  // namespace markloop::io
