#include "replay/paper_format.hpp"

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string_view>

namespace markloop::replay {

namespace {

// Splits a whole file into whitespace-separated tokens, remembering lines.
class Tokens {
 public:
  bool open(const std::string& path, std::string& error) {
    std::ifstream in(path, std::ios::binary);
    if (!in) {
      error = path + ": cannot open file";
      return false;
    }
    std::ostringstream content;
    content << in.rdbuf();
    text_ = content.str();
    path_ = path;
    return true;
  }
  // Next token and its line; false at the end.
  bool next(std::string_view& token, int& line) {
    while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
    if (pos_ >= text_.size()) return false;
    const std::size_t start = pos_;
    while (pos_ < text_.size() && !std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    token = std::string_view(text_).substr(start, pos_ - start);
    line = line_;
    return true;
  }
  int line() const { return line_; }
  const std::string& path() const { return path_; }
  std::string where(int line) const { return path_ + ":" + std::to_string(line) + ": "; }

 private:
  std::string text_;
  std::string path_;
  std::size_t pos_ = 0;
  int line_ = 1;
};

template <typename T>
bool parse_number(std::string_view token, T& value) {
  const char* first = token.data();
  const char* last = token.data() + token.size();
  if (first != last && *first == '+') ++first;  // from_chars rejects a leading '+'
  const auto [end, ec] = std::from_chars(first, last, value);
  if (ec != std::errc() || end != last) return false;
  if constexpr (std::is_floating_point_v<T>) return std::isfinite(value);
  return true;
}

std::vector<std::string_view> split(std::string_view line, char separator) {
  std::vector<std::string_view> fields;
  std::size_t start = 0;
  for (;;) {
    const std::size_t end = line.find(separator, start);
    if (end == std::string_view::npos) {
      fields.push_back(line.substr(start));
      return fields;
    }
    fields.push_back(line.substr(start, end - start));
    start = end + 1;
  }
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

}  // namespace

Label LabelTable::intern(const std::string& name) {
  const auto [it, inserted] = ids_.try_emplace(name, static_cast<Label>(names_.size()));
  if (inserted) names_.push_back(name);
  return it->second;
}

bool load_markings(const std::string& path, std::vector<MarkingRecord>& records,
                   std::string& error) {
  Tokens tokens;
  if (!tokens.open(path, error)) return false;
  records.clear();
  std::string_view token;
  int line = 1;
  if (!tokens.next(token, line)) {
    error = tokens.where(tokens.line()) + "empty file: expected the number of records";
    return false;
  }
  long long count = 0;
  if (!parse_number(token, count) || count < 0) {
    error = tokens.where(line) + "expected the number of records, found '" + std::string(token) + "'";
    return false;
  }
  records.reserve(static_cast<std::size_t>(std::min<long long>(count, 1 << 24)));
  static constexpr const char* kFields[] = {"frame index", "x", "y", "z", "label"};
  for (long long i = 0; i < count; ++i) {
    MarkingRecord r;
    for (int field = 0; field < 5; ++field) {
      if (!tokens.next(token, line)) {
        error = tokens.where(tokens.line()) + "the file declares " + std::to_string(count) +
                " records but ends inside record " + std::to_string(i + 1) + " (missing " +
                kFields[field] + ")";
        return false;
      }
      if (field == 0) r.line = line;
      bool ok = true;
      switch (field) {
        case 0: ok = parse_number(token, r.frame) && r.frame >= 0; break;
        case 1: ok = parse_number(token, r.x); break;
        case 2: ok = parse_number(token, r.y); break;
        case 3: ok = parse_number(token, r.z); break;
        default: r.label = std::string(token); break;
      }
      if (!ok) {
        error = tokens.where(line) + "record " + std::to_string(i + 1) + ": " + kFields[field] +
                " is not " + (field == 0 ? "a non-negative integer" : "a finite number") +
                ": '" + std::string(token) + "'";
        return false;
      }
    }
    records.push_back(std::move(r));
  }
  if (tokens.next(token, line)) {
    error = tokens.where(line) + "more data after the " + std::to_string(count) +
            " declared records: '" + std::string(token) + "'";
    return false;
  }
  return true;
}

namespace {

Pose2 kitti_to_ground(const double m[12]) {
  // Camera axes x right, y down, z ahead; ground frame x ahead, y left.
  return {m[11], -m[3], std::atan2(-m[2], m[10])};
}

bool read_kitti_lines(std::istream& in, const std::string& path, int first_line,
                      std::vector<Pose2>& poses, std::string& error) {
  std::string text;
  for (int line = first_line; std::getline(in, text); ++line) {
    const std::string_view content = trim(text);
    if (content.empty()) continue;
    std::istringstream fields{std::string(content)};
    double m[12];
    int n = 0;
    std::string token;
    while (fields >> token) {
      if (n == 12) {
        error = path + ":" + std::to_string(line) + ": more than 12 numbers in a pose line";
        return false;
      }
      if (!parse_number(std::string_view(token), m[n])) {
        error = path + ":" + std::to_string(line) + ": not a number: '" + token + "'";
        return false;
      }
      ++n;
    }
    if (n != 12) {
      error = path + ":" + std::to_string(line) + ": expected 12 numbers (a 3x4 [R|t] pose), found " +
              std::to_string(n);
      return false;
    }
    poses.push_back(kitti_to_ground(m));
  }
  return true;
}

}  // namespace

bool load_kitti_poses(const std::string& path, std::vector<Pose2>& poses, std::string& error) {
  std::ifstream in(path);
  if (!in) {
    error = path + ": cannot open file";
    return false;
  }
  poses.clear();
  return read_kitti_lines(in, path, 1, poses, error);
}

bool load_truth(const std::string& path, std::vector<Pose2>& poses, std::string& error,
                std::vector<double>* times) {
  std::ifstream in(path);
  if (!in) {
    error = path + ": cannot open file";
    return false;
  }
  poses.clear();
  if (times != nullptr) times->clear();
  std::string header;
  std::getline(in, header);
  if (trim(header) != "frame,t,x,y,yaw") {
    in.clear();
    in.seekg(0);
    return read_kitti_lines(in, path, 1, poses, error);
  }
  std::string text;
  for (int line = 2; std::getline(in, text); ++line) {
    if (trim(text).empty()) continue;
    const auto fields = split(trim(text), ',');
    double values[5];
    bool ok = fields.size() == 5;
    for (std::size_t i = 0; ok && i < 5; ++i) ok = parse_number(trim(fields[i]), values[i]);
    if (!ok) {
      error = path + ":" + std::to_string(line) + ": expected frame,t,x,y,yaw numbers";
      return false;
    }
    if (values[0] != static_cast<double>(poses.size())) {
      error = path + ":" + std::to_string(line) + ": expected frame " + std::to_string(poses.size());
      return false;
    }
    poses.push_back({values[2], values[3], values[4]});
    if (times != nullptr) times->push_back(values[1]);
  }
  return true;
}

}  // namespace markloop::replay
