// Calibration and detector settings are OpenCV FileStorage files (YAML, XML
// or JSON). They are read here, checked for what OpenCV's reader cannot take,
// and parsed from memory, so that a bad file gives an error and never a hang.
#pragma once

#include <cstddef>
#include <string>

#include <opencv2/core/persistence.hpp>

#include "app/common/result.hpp"

namespace markloop::perception {

// Larger files are no calibration (OpenCV's own are a few kB).
inline constexpr std::size_t kMaxStorageFileBytes = std::size_t{1} << 20;
// Deeper files are no calibration either (OpenCV's own are 2 or 3 levels).
inline constexpr int kMaxStorageNesting = 32;

// The file at `path` opened for reading; an error ("PATH: ..." or
// "PATH:LINE: ...") when it cannot be read, is too large, is nested
// deeper than kMaxStorageNesting, holds a line OpenCV 4.6's YAML reader
// never returns from (one beginning with "----" followed by more text), or
// is no FileStorage file. OpenCV reports syntax
// errors by throwing cv::Exception: callers catch it.
Result<cv::FileStorage> open_storage_file(const std::string& path);

}  // namespace markloop::perception
