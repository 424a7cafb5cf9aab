// Calibration and detector settings are OpenCV FileStorage files (YAML, XML
// or JSON). They are read here, checked for what OpenCV's reader cannot take,
// and parsed from memory, so that a bad file gives an error and never a hang.
#pragma once

#include <cstddef>
#include <optional>
#include <string>

#include <opencv2/core/persistence.hpp>

namespace markloop::perception {

// Larger files are no calibration (OpenCV's own are a few kB).
inline constexpr std::size_t kMaxStorageFileBytes = std::size_t{1} << 20;

// The file at `path` opened for reading; none with `error` set ("PATH: ..."
// or "PATH:LINE: ...") when it cannot be read, is too large, holds a line
// OpenCV 4.6's YAML reader never returns from (one beginning with "----"
// followed by more text), or is no FileStorage file. OpenCV reports syntax
// errors by throwing cv::Exception: callers catch it.
std::optional<cv::FileStorage> open_storage_file(const std::string& path, std::string& error);

}  // namespace markloop::perception
