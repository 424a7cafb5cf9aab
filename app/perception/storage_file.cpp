#include "perception/storage_file.hpp"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <string_view>

namespace markloop::perception {
namespace {

// OpenCV 4.6's YAML reader loops for ever on a document such as
// "%YAML:1.0\n----a\nb\n" (found by the calibration fuzz target): a line whose
// first non-blank characters are four dashes. No calibration needs one.
std::size_t first_line_with_long_dashes(std::string_view text) {
  std::size_t line = 1;
  for (std::size_t begin = 0; begin < text.size(); ++line) {
    std::size_t end = text.find('\n', begin);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view row = text.substr(begin, end - begin);
    const std::size_t first = row.find_first_not_of(" \t");
    if (first != std::string_view::npos && row.substr(first).starts_with("----")) return line;
    begin = end + 1;
  }
  return 0;
}

}  // namespace

std::optional<cv::FileStorage> open_storage_file(const std::string& path, std::string& error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    error = path + ": cannot open: " + std::strerror(errno);
    return std::nullopt;
  }
  std::string text(kMaxStorageFileBytes + 1, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  if (in.bad()) {
    error = path + ": read error";
    return std::nullopt;
  }
  text.resize(static_cast<std::size_t>(in.gcount()));
  if (text.size() > kMaxStorageFileBytes) {
    error = path + ": larger than " + std::to_string(kMaxStorageFileBytes >> 20) +
            " MiB: not a calibration file";
    return std::nullopt;
  }
  if (const std::size_t line = first_line_with_long_dashes(text); line != 0) {
    error = path + ":" + std::to_string(line) +
            ": a line beginning with \"----\" (a YAML document marker is \"---\" alone)";
    return std::nullopt;
  }
  cv::FileStorage fs(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
  if (!fs.isOpened()) {
    error = path + ": not an OpenCV YAML, XML or JSON file";
    return std::nullopt;
  }
  return fs;
}

}  // namespace markloop::perception
