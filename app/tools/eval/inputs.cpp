#include "app/tools/eval/inputs.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string_view>

#include "app/perception/marking_classes.hpp"
#include "app/tools/common/tool_files.hpp"
#include "app/tools/replay/paper_format.hpp"

namespace markloop::eval {

namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> split_fields(std::string_view line) {
  std::vector<std::string_view> fields;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = line.find(',', start);
    fields.push_back(trim(line.substr(start, comma - start)));
    if (comma == std::string_view::npos) return fields;
    start = comma + 1;
  }
}

std::optional<double> to_number(std::string_view text) {
  if (text.empty() || text.size() > 64) return std::nullopt;
  char buffer[65];
  text.copy(buffer, text.size());
  buffer[text.size()] = '\0';
  char* end = nullptr;
  errno = 0;
  const double value = std::strtod(buffer, &end);
  if (end != buffer + text.size() || errno != 0 || !std::isfinite(value)) return std::nullopt;
  return value;
}

// Reads a CSV with a fixed header line, calling `row(fields)` for each
// non-empty data line; `row` returns an error text or an empty string. A
// file may end its header with the columns `later` (added since the first
// version): its rows then hold them too.
class CsvFile {
 public:
  template <typename Row>
  static Status read(const std::string& path, std::string_view header, Row&& row,
                     std::string_view later = {}) {
    const Result<std::string> read = tools::read_input(path, kMaxInputBytes, "a CSV file");
    if (!read) return read.error();
    const std::string& text = *read;
    Progress progress(path, count_lines(text));
    tools::Lines lines(text);
    std::string_view line;
    const std::string full =
        later.empty() ? std::string(header) : std::string(header) + "," + std::string(later);
    const std::string_view given = lines.next(line) ? trim(line) : std::string_view{};
    if (given != header && given != full)
      return markloop::error(path + ":1: expected the header '" + full + "'");
    if (given == full) header = full;
    const std::size_t columns = split_fields(header).size();
    while (lines.next(line)) {
      if ((lines.number() & 0xFFF) == 0) progress.update(lines.number());
      if (trim(line).empty()) continue;
      const auto fields = split_fields(trim(line));
      std::string problem;
      if (fields.size() != columns)
        problem = "expected " + std::to_string(columns) + " comma-separated fields (" + std::string(header) +
                  "), found " + std::to_string(fields.size());
      else
        problem = row(fields);
      if (!problem.empty())
        return markloop::error(path + ":" + std::to_string(lines.number()) + ": " + problem);
    }
    progress.finish();
    return {};
  }
};

// The largest magnitude a number field may have: positions in metres as
// for poses, angles unwrapped but not without end, image corners far off
// the image but not at infinity.
double field_limit(std::string_view name) {
  constexpr double kMaxPixel = 1e6;
  if (name == "heading" || name == "car_yaw") return replay::kMaxYaw_rad;
  if (name.size() == 2 && (name[0] == 'x' || name[0] == 'y') && name[1] >= '1' && name[1] <= '4')
    return kMaxPixel;
  return replay::kMaxPoseCoordinate_m;
}

// Field parsers: on failure they return false and describe the problem.
bool number_field(std::string_view name, std::string_view text, double& out, std::string& problem) {
  const auto value = to_number(text);
  if (!value) {
    problem = std::string(name) + " is not a finite number: '" + std::string(text) + "'";
    return false;
  }
  if (std::abs(*value) > field_limit(name)) {
    char limit[32];
    std::snprintf(limit, sizeof limit, "%g", field_limit(name));
    problem = std::string(name) + " " + std::string(text) + " is out of range (|" + std::string(name) +
              "| <= " + limit + ")";
    return false;
  }
  out = *value;
  return true;
}

bool whole_field(std::string_view name, std::string_view text, double limit, std::uint32_t& out,
                 std::string& problem) {
  const auto value = to_number(text);
  if (!value || *value < 0 || *value != std::floor(*value) || *value >= limit) {
    problem = std::string(name) + " is not a whole number below " +
              std::to_string(static_cast<unsigned long long>(limit)) + ": '" + std::string(text) + "'";
    return false;
  }
  out = static_cast<std::uint32_t>(*value);
  return true;
}

bool frame_field(std::string_view name, std::string_view text, std::size_t frame_count, FrameIndex& out,
                 std::string& problem) {
  std::uint32_t frame = 0;
  if (!whole_field(name, text, 4294967296.0, frame, problem)) return false;
  if (frame >= frame_count) {
    problem = std::string(name) + " " + std::to_string(frame) + " is beyond the truth's " +
              std::to_string(frame_count) + " frames (frames.csv)";
    return false;
  }
  out = frame;
  return true;
}

bool class_field(std::string_view name, std::string_view text, Label& out, std::string& problem) {
  const auto label = perception::marking_class_from_name(text);
  if (!label) {
    problem = std::string(name) + " '" + std::string(text) + "' is not a marking class";
    return false;
  }
  out = *label;
  return true;
}

bool quad_fields(const std::vector<std::string_view>& fields, std::size_t first, Quad& quad,
                 std::string& problem) {
  static constexpr const char* kNames[8] = {"x1", "y1", "x2", "y2", "x3", "y3", "x4", "y4"};
  for (std::size_t i = 0; i < 8; ++i)
    if (!number_field(kNames[i], fields[first + i], quad[i / 2][i % 2], problem)) return false;
  return true;
}

}  // namespace

Progress::Progress(std::string what, std::size_t total_lines, std::size_t min_lines)
    : what_(std::move(what)), total_(total_lines), enabled_(total_lines >= min_lines) {}

void Progress::update(std::size_t lines_done) {
  if (!enabled_) return;
  while (next_tenth_ < 10 && lines_done * 10 >= next_tenth_ * total_) {
    std::fprintf(stderr, "markloop-eval: %s: %zu%% (%zu of %zu lines)\n", what_.c_str(), next_tenth_ * 10,
                 lines_done, total_);
    ++next_tenth_;
  }
}

void Progress::finish() {
  if (enabled_) std::fprintf(stderr, "markloop-eval: %s: done (%zu lines)\n", what_.c_str(), total_);
  enabled_ = false;
}

std::size_t count_lines(std::string_view text) {
  return static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n'));
}

Result<std::vector<WorldMarking>> load_world_markings(const std::string& path) {
  std::vector<WorldMarking> out;
  const Status read =
      CsvFile::read(path, "id,class,x,y,heading", [&](const std::vector<std::string_view>& f) {
        std::string problem;
        WorldMarking m;
        if (whole_field("id", f[0], 4294967296.0, m.id, problem) &&
            class_field("class", f[1], m.label, problem) && number_field("x", f[2], m.x, problem) &&
            number_field("y", f[3], m.y, problem) && number_field("heading", f[4], m.heading, problem))
          out.push_back(m);
        return problem;
      });
  if (!read) return read.error();
  return out;
}

Result<std::vector<VisibleMarking>> load_visible(const std::string& path, std::size_t frame_count) {
  std::vector<VisibleMarking> out;
  const Status read = CsvFile::read(
      path, "frame,id,class,x1,y1,x2,y2,x3,y3,x4,y4", [&](const std::vector<std::string_view>& f) {
        std::string problem;
        VisibleMarking m;
        if (frame_field("frame", f[0], frame_count, m.frame, problem) &&
            whole_field("id", f[1], 4294967296.0, m.id, problem) &&
            class_field("class", f[2], m.label, problem) && quad_fields(f, 3, m.quad, problem))
          out.push_back(m);
        return problem;
      });
  if (!read) return read.error();
  std::stable_sort(out.begin(), out.end(),
                   [](const VisibleMarking& a, const VisibleMarking& b) { return a.frame < b.frame; });
  return out;
}

Result<std::vector<DetectionRecord>> load_detections(const std::string& path, std::size_t frame_count) {
  std::vector<DetectionRecord> out;
  const Status read = CsvFile::read(
      path, "frame,label,score,x1,y1,x2,y2,x3,y3,x4,y4,ground_x,ground_y",
      [&](const std::vector<std::string_view>& f) {
        std::string problem;
        DetectionRecord d;
        std::uint32_t turned = 0;
        if (!frame_field("frame", f[0], frame_count, d.frame, problem) ||
            !class_field("label", f[1], d.label, problem) || !number_field("score", f[2], d.score, problem) ||
            !quad_fields(f, 3, d.quad, problem) || !number_field("ground_x", f[11], d.ground_x, problem) ||
            !number_field("ground_y", f[12], d.ground_y, problem) ||
            (f.size() > 13 && !whole_field("turned", f[13], 2.0, turned, problem)))
          return problem;
        d.turned = turned == 1;
        if (d.score < 0.0 || d.score > 1.0) return "score " + std::string(f[2]) + " is outside [0, 1]";
        out.push_back(d);
        return problem;
      },
      "turned");
  if (!read) return read.error();
  std::stable_sort(out.begin(), out.end(),
                   [](const DetectionRecord& a, const DetectionRecord& b) { return a.frame < b.frame; });
  return out;
}

Result<std::vector<LandmarkRecord>> load_landmarks(const std::string& path, std::size_t frame_count) {
  std::vector<LandmarkRecord> out;
  const Status read = CsvFile::read(
      path, "label,observations,first_frame,last_frame,x,y,car_x,car_y,car_yaw,has_car_pose",
      [&](const std::vector<std::string_view>& f) {
        std::string problem;
        LandmarkRecord l;
        std::uint32_t has_car_pose = 0;
        std::uint32_t facing = 0;
        if (!class_field("label", f[0], l.label, problem) ||
            !whole_field("observations", f[1], 65536.0, l.observations, problem) ||
            !frame_field("first_frame", f[2], frame_count, l.first_frame, problem) ||
            !frame_field("last_frame", f[3], frame_count, l.last_frame, problem) ||
            !number_field("x", f[4], l.x, problem) || !number_field("y", f[5], l.y, problem) ||
            !number_field("car_x", f[6], l.car_x, problem) ||
            !number_field("car_y", f[7], l.car_y, problem) ||
            !number_field("car_yaw", f[8], l.car_yaw, problem) ||
            !whole_field("has_car_pose", f[9], 2.0, has_car_pose, problem) ||
            (f.size() > 10 && !whole_field("facing", f[10], 3.0, facing, problem)))
          return problem;
        if (l.first_frame > l.last_frame)
          return "first_frame " + std::string(f[2]) + " is after last_frame " + std::string(f[3]);
        l.has_car_pose = has_car_pose == 1;
        l.facing = static_cast<Facing>(facing);
        out.push_back(l);
        return problem;
      },
      "facing");
  if (!read) return read.error();
  return out;
}

}  // namespace markloop::eval
