// Still images (PNG or JPEG) read for the host tools: markloop-detect and
// markloop-train. Built with the tools only (it needs OpenCV's imgcodecs,
// which the ECU does not link).
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include <opencv2/core/mat.hpp>

namespace markloop::io {

enum class StillCheck : std::uint8_t {
  kComplete,
  kUnknownFormat,    // neither PNG's nor JPEG's signature
  kTruncatedPng,     // ends inside a chunk or before the IEND chunk
  kTruncatedJpeg,    // no end-of-image marker after the last scan
};

// Whether `bytes` hold a whole PNG or JPEG file, judged by its structure
// alone (no decoding). libjpeg decodes a truncated JPEG without failing and
// fills the missing rows with grey, which the detector would then search as
// road; so the tools refuse such a file instead.
StillCheck check_still(std::span<const std::uint8_t> bytes);

// Reads `path`, checks it with check_still() and decodes it to 8-bit grey.
// On failure returns an empty Mat and sets `error` to what was wrong (without
// the path: the caller adds it).
cv::Mat read_grey_still(const std::string& path, std::string& error);

}  // namespace markloop::io
