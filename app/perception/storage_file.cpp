#include "app/perception/storage_file.hpp"

#include <algorithm>
#include <cctype>
#include <string_view>
#include <vector>

#include "platform/files.hpp"

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

// OpenCV's parsers descend recursively, one call per level, and overflow the
// stack on a document nested a few ten thousand levels deep. A calibration is
// a few levels deep: anything deeper than kMaxStorageNesting is refused,
// counting YAML/JSON brackets and braces (comments too: a parser that skips
// them could be fooled about where one starts), YAML block sequences opened
// on one line ("- - -"), indentation and XML elements. Returns the first line that
// goes too deep, 0 when none does.
// YAML block sequences opened at the start of a line ("- - - x") and its
// indentation: true when they go deeper than the limit.
bool line_start_too_deep(std::string_view text, std::size_t begin) {
  const auto blank = [&](std::size_t j) { return j < text.size() && (text[j] == ' ' || text[j] == '\t'); };
  std::size_t j = begin;
  while (blank(j)) ++j;
  int dashes = 0;
  while (j < text.size() && text[j] == '-' && blank(j + 1)) {
    ++dashes;
    for (++j; blank(j);) ++j;
  }
  return dashes > kMaxStorageNesting || j - begin > 8 * std::size_t{kMaxStorageNesting};
}

std::size_t first_line_too_deep(std::string_view text) {
  std::size_t line = 1;
  int brackets = 0, elements = 0;
  char quote = 0;
  if (line_start_too_deep(text, 0)) return line;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    const char next = i + 1 < text.size() ? text[i + 1] : '\0';
    if (c == '\n') {
      ++line;
      if (quote == '\'') quote = 0;  // a calibration's single-quoted scalars fit on a line
      if (line_start_too_deep(text, i + 1)) return line;
      continue;
    }
    if (quote != 0) {
      if (c == '\\' && quote == '"')
        ++i;
      else if (c == quote)
        quote = 0;
      continue;
    }
    switch (c) {
      case '"':
      case '\'':
        quote = c;
        break;
      case '[':
      case '{':
        ++brackets;
        break;
      case ']':
      case '}':
        --brackets;
        break;
      case '<':
        if (next == '/')
          --elements;
        else if (next != '?' && next != '!')
          ++elements;
        break;
      case '/':
        if (next == '>') --elements;
        break;
      default:
        break;
    }
    if (brackets > kMaxStorageNesting || elements > kMaxStorageNesting) return line;
  }
  return 0;
}

// OpenCV keeps one of two equal keys without a word; a calibration that
// names a setting twice is a mistake to report. YAML's top-level keys only
// (a line beginning with a name and a colon). Returns the second line, 0
// when no key repeats; `key` names it.
std::size_t first_repeated_key(std::string_view text, std::string& key) {
  std::vector<std::string_view> seen;
  std::size_t line = 0;
  for (std::size_t begin = 0; begin < text.size();) {
    ++line;
    std::size_t end = text.find('\n', begin);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view row = text.substr(begin, end - begin);
    begin = end + 1;
    std::size_t n = 0;
    while (n < row.size() && (std::isalnum(static_cast<unsigned char>(row[n])) != 0 || row[n] == '_')) ++n;
    if (n == 0 || n >= row.size() || row[n] != ':') continue;
    const std::string_view name = row.substr(0, n);
    if (std::find(seen.begin(), seen.end(), name) != seen.end()) {
      key = name;
      return line;
    }
    seen.push_back(name);
  }
  return 0;
}

}  // namespace

Result<cv::FileStorage> open_storage_file(const std::string& path) {
  std::string text;
  // The calibration is opened twice (camera, detector settings).
  std::error_code ec = platform::refuse_pipe(path.c_str());
  if (!ec) ec = platform::read_file_bounded(path.c_str(), kMaxStorageFileBytes, text);
  if (ec) {
    return error(platform::describe_read_error(path, ec, kMaxStorageFileBytes, "a calibration file"));
  }
  if (const std::size_t line = first_line_with_long_dashes(text); line != 0) {
    return error(path + ":" + std::to_string(line) +
                 ": a line beginning with \"----\" (a YAML document marker is \"---\" alone)");
  }
  if (const std::size_t line = first_line_too_deep(text); line != 0) {
    return error(path + ":" + std::to_string(line) + ": nested more than " +
                 std::to_string(kMaxStorageNesting) + " levels deep: not a calibration file");
  }
  std::string key;
  if (const std::size_t line = first_repeated_key(text, key); line != 0) {
    return error(path + ":" + std::to_string(line) + ": " + key + " is given twice");
  }
  cv::FileStorage fs(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
  if (!fs.isOpened()) {
    return error(path + ": not an OpenCV YAML, XML or JSON file");
  }
  return fs;
}

}  // namespace markloop::perception
