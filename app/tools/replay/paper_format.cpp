#include "app/tools/replay/paper_format.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <optional>
#include <string_view>
#include <utility>

#include "app/perception/marking_classes.hpp"
#include "app/tools/common/tool_files.hpp"

namespace markloop::replay {

namespace {

// Splits a whole file into whitespace-separated tokens, remembering lines.
class Tokens {
 public:
  Status open(const std::string& path) {
    Result<std::string> text = tools::read_input(path, kMaxMarkingsBytes, "a markings file");
    if (!text) return text.error();
    text_ = std::move(text).value();
    path_ = path;
    return {};
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
  std::size_t size() const { return text_.size(); }
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

namespace {

// The record count the file declares first.
Result<long long> read_count(Tokens& tokens) {
  std::string_view token;
  int line = 1;
  if (!tokens.next(token, line))
    return error(tokens.where(tokens.line()) + "empty file: expected the number of records");
  long long count = 0;
  if (!parse_number(token, count) || count < 0)
    return error(tokens.where(line) + "expected the number of records, found '" + std::string(token) + "'");
  return count;
}

// One field of record `index` (from 0) read from `token`; false when it is
// not what the field holds.
bool read_field(int field, std::string_view token, MarkingRecord& r) {
  switch (field) {
    case 0:
      return parse_number(token, r.frame) && r.frame >= 0;
    case 1:
      return parse_number(token, r.x);
    case 2:
      return parse_number(token, r.y);
    case 3:
      return parse_number(token, r.z);
    default:
      r.label = std::string(token.substr(0, kMaxLabelLength + 1));
      r.facing = facing_read_upright(r.label);
      return true;
  }
}

// Record `index` (from 0) of the `count` declared: frame x y z label.
Result<MarkingRecord> read_record(Tokens& tokens, long long index, long long count) {
  static constexpr const char* kFields[] = {"frame index", "x", "y", "z", "label"};
  MarkingRecord r;
  const std::string record = "record " + std::to_string(index + 1);
  std::string_view token;
  int line = 1;
  for (int field = 0; field < 5; ++field) {
    if (!tokens.next(token, line))
      return error(tokens.where(tokens.line()) + "the file declares " + std::to_string(count) +
                   " records but ends inside " + record + " (missing " + kFields[field] + ")");
    if (field == 0) r.line = line;
    const bool ok = read_field(field, token, r);
    if (field == 4 && token.size() > kMaxLabelLength)
      return error(tokens.where(line) + record + ": label is longer than " + std::to_string(kMaxLabelLength) +
                   " characters");
    if (!ok)
      return error(tokens.where(line) + record + ": " + kFields[field] + " is not " +
                   (field == 0 ? "a non-negative integer" : "a finite number") + ": '" + std::string(token) +
                   "'");
  }
  return r;
}

}  // namespace

Facing facing_read_upright(std::string_view label) {
  const std::optional<Label> known = perception::marking_class_from_name(label);
  return known ? perception::facing_of(*known, false) : Facing::kAny;
}

Result<std::vector<MarkingRecord>> load_markings(const std::string& path) {
  Tokens tokens;
  std::string problem;
  if (Status opened = tokens.open(path); !opened) return opened.error();
  const Result<long long> count = read_count(tokens);
  if (!count) return count.error();
  std::vector<MarkingRecord> records;
  // A record takes at least 10 characters ("0 0 0 0 A\n"): the declared
  // count reserves no more than the file can hold.
  records.reserve(std::min(static_cast<std::size_t>(*count), tokens.size() / 10));
  for (long long i = 0; i < *count; ++i) {
    Result<MarkingRecord> record = read_record(tokens, i, *count);
    if (!record) return record.error();
    records.push_back(std::move(record).value());
  }
  std::string_view token;
  int line = 1;
  if (tokens.next(token, line))
    return error(tokens.where(line) + "more data after the " + std::to_string(*count) +
                 " declared records: '" + std::string(token) + "'");
  return records;
}

namespace {

Pose2 kitti_to_ground(const double m[12]) {
  // Camera axes x right, y down, z ahead; ground frame x ahead, y left.
  return {m[11], -m[3], std::atan2(-m[2], m[10])};
}

std::string where(const std::string& path, std::size_t line) {
  return path + ":" + std::to_string(line) + ": ";
}

// Farther from the origin than any road: a file in other units, or not poses.
bool beyond_any_road(const Pose2& p) {
  return std::abs(p.x) > kMaxPoseCoordinate_m || std::abs(p.y) > kMaxPoseCoordinate_m;
}

std::string beyond_any_road_text(const Pose2& p) {
  char text[160];
  std::snprintf(text, sizeof text,
                "position (%g, %g) m lies beyond %.0f km of the origin: not a pose in metres", p.x + 0.0,
                p.y + 0.0, kMaxPoseCoordinate_m / 1000.0);
  return text;
}

// One line of 12 numbers, a 3x4 [R|t] pose; the problem in `problem`.
bool parse_kitti_line(std::string_view content, Pose2& pose, std::string& problem) {
  double m[12];
  int n = 0;
  for (;;) {
    while (!content.empty() && std::isspace(static_cast<unsigned char>(content.front())))
      content.remove_prefix(1);
    if (content.empty()) break;
    std::size_t length = 0;
    while (length < content.size() && !std::isspace(static_cast<unsigned char>(content[length]))) ++length;
    const std::string_view token = content.substr(0, length);
    content.remove_prefix(length);
    if (n == 12) {
      problem = "more than 12 numbers in a pose line";
      return false;
    }
    if (!parse_number(token, m[n])) {
      problem = "not a number: '" + std::string(token) + "'";
      return false;
    }
    ++n;
  }
  if (n != 12) {
    problem = "expected 12 numbers (a 3x4 [R|t] pose), found " + std::to_string(n);
    return false;
  }
  pose = kitti_to_ground(m);
  if (beyond_any_road(pose)) {
    problem = beyond_any_road_text(pose);
    return false;
  }
  return true;
}

bool read_kitti_lines(tools::Lines& lines, const std::string& path, std::vector<Pose2>& poses,
                      std::string& error) {
  std::string_view text;
  while (lines.next(text)) {
    const std::string_view content = trim(text);
    if (content.empty()) continue;
    Pose2 pose;
    std::string problem;
    if (!parse_kitti_line(content, pose, problem)) {
      error = where(path, lines.number()) + problem;
      return false;
    }
    poses.push_back(pose);
  }
  return true;
}

// frames.csv after its header: frame,t,x,y,yaw per line, frames 0, 1, ...
bool read_frames_csv_lines(tools::Lines& lines, const std::string& path, std::vector<Pose2>& poses,
                           std::vector<double>* times, std::string& error) {
  std::string_view text;
  while (lines.next(text)) {
    if (trim(text).empty()) continue;
    const auto fields = split(trim(text), ',');
    double values[5];
    bool ok = fields.size() == 5;
    for (std::size_t i = 0; ok && i < 5; ++i) ok = parse_number(trim(fields[i]), values[i]);
    if (!ok) {
      error = where(path, lines.number()) + "expected frame,t,x,y,yaw numbers";
      return false;
    }
    if (values[0] != static_cast<double>(poses.size())) {
      error = where(path, lines.number()) + "expected frame " + std::to_string(poses.size());
      return false;
    }
    const Pose2 pose{values[2], values[3], values[4]};
    if (beyond_any_road(pose)) {
      error = where(path, lines.number()) + beyond_any_road_text(pose);
      return false;
    }
    if (std::abs(values[1]) > kMaxTime_s || std::abs(pose.yaw) > kMaxYaw_rad) {
      error = where(path, lines.number()) + (std::abs(values[1]) > kMaxTime_s ? "t" : "yaw") +
              " is out of range (|t| <= 3.2e9 s, |yaw| <= 1e6 rad)";
      return false;
    }
    poses.push_back(pose);
    if (times != nullptr) times->push_back(values[1]);
  }
  return true;
}

constexpr std::string_view kFramesHeader = "frame,t,x,y,yaw";

}  // namespace

Result<std::vector<Pose2>> load_kitti_poses(const std::string& path) {
  std::vector<Pose2> poses;
  const Result<std::string> read = tools::read_input(path, kMaxPosesBytes, "a poses file");
  if (!read) return read.error();
  const std::string& text = *read;
  std::string problem;
  tools::Lines lines(text);
  if (!read_kitti_lines(lines, path, poses, problem)) return error(problem);
  return poses;
}

Result<TruePoses> load_truth(const std::string& path) {
  TruePoses truth;
  const Result<std::string> read = tools::read_input(path, kMaxPosesBytes, "a ground truth file");
  if (!read) return read.error();
  const std::string& text = *read;
  std::string problem;
  tools::Lines lines(text);
  std::string_view header;
  if (lines.next(header) && trim(header) == kFramesHeader) {
    if (!read_frames_csv_lines(lines, path, truth.poses, &truth.times, problem)) return error(problem);
    return truth;
  }
  tools::Lines from_start(text);
  if (!read_kitti_lines(from_start, path, truth.poses, problem)) return error(problem);
  return truth;
}

Result<TruePoses> load_frames_csv(const std::string& path) {
  TruePoses truth;
  const Result<std::string> read = tools::read_input(path, kMaxPosesBytes, "a frames.csv file");
  if (!read) return read.error();
  const std::string& text = *read;
  std::string problem;
  tools::Lines lines(text);
  std::string_view header;
  if (!lines.next(header) || trim(header) != kFramesHeader)
    return error(where(path, 1) + "expected the header '" + std::string(kFramesHeader) + "'");
  if (!read_frames_csv_lines(lines, path, truth.poses, &truth.times, problem)) return error(problem);
  return truth;
}

}  // namespace markloop::replay
