#include "app/tools/train/dataset.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string_view>
#include <utility>

#include "app/tools/common/tool_files.hpp"

namespace markloop::perception::train {
namespace {

// The data lines of a CSV file read whole (no quoting in ours), split at
// commas, with errors as "FILE:LINE: what".
class CsvReader {
 public:
  CsvReader(std::string path, std::size_t max_bytes) : path_(std::move(path)), max_bytes_(max_bytes) {}

  // Reads the file and checks that its header line starts with
  // `header_start`; `header` is the whole header, for the error.
  bool read_header(const std::string& header_start, const std::string& header, std::string& error) {
    Result<std::string> text = tools::read_input(path_, max_bytes_, "an annotation file");
    if (!text) {
      error = text.message();
      return false;
    }
    text_ = std::move(text).value();
    lines_ = tools::Lines(text_);
    std::string_view line;
    if (!lines_.next(line) || !line.starts_with(header_start)) {
      error = path_ + ":1: header must be " + header;
      return false;
    }
    return true;
  }

  // The fields of the next non-empty line; false at the end of the file.
  bool next(std::vector<std::string>& fields) {
    std::string_view line;
    while (lines_.next(line)) {
      if (line.empty()) continue;
      fields = split_csv_line(line);
      return true;
    }
    return false;
  }

  // Sets `error` for the current line; false, to be returned.
  bool fail(const std::string& what, std::string& error) const {
    error = path_ + ":" + std::to_string(lines_.number()) + ": " + what;
    return false;
  }

 private:
  // As std::getline splits: no field after a last comma.
  static std::vector<std::string> split_csv_line(std::string_view line) {
    std::vector<std::string> fields;
    while (!line.empty()) {
      const std::size_t comma = line.find(',');
      fields.emplace_back(line.substr(0, comma));
      line = comma == std::string_view::npos ? std::string_view() : line.substr(comma + 1);
    }
    return fields;
  }

  std::string path_;
  std::size_t max_bytes_;
  std::string text_;
  tools::Lines lines_{std::string_view()};
};

// The frames of a drive: frames.csv's data lines (one per frame).
bool count_drive_frames(const std::string& dir, long& frames, std::string& error) {
  CsvReader csv(dir + "/frames.csv", kMaxDriveFileBytes);
  if (!csv.read_header("frame,t,x,y,yaw", "frame,t,x,y,yaw", error)) return false;
  frames = 0;
  std::vector<std::string> fields;
  while (csv.next(fields)) ++frames;
  return true;
}

bool read_annotations(const std::string& dir, std::vector<AnnotatedImage>& images, std::string& error) {
  CsvReader csv(dir + "/annotations.csv", kMaxAnnotationBytes);
  if (!csv.read_header("image,label,x1,y1", "image,label,x1,y1,x2,y2,x3,y3,x4,y4", error)) return false;
  std::map<std::string, AnnotatedImage> by_name;
  std::vector<std::string> fields;
  while (csv.next(fields)) {
    const auto fail = [&](const std::string& what) { return csv.fail(what, error); };
    if (fields.size() != 10) return fail("expected 10 fields, found " + std::to_string(fields.size()));
    if (fields[0].empty() || fields[0].find('/') != std::string::npos)
      return fail("bad image name '" + fields[0] + "'");
    if (fields[1].empty()) return fail("empty label");
    Annotation a;
    a.label = fields[1];
    for (int i = 0; i < 8; ++i) {
      char* end = nullptr;
      const double v = std::strtod(fields[2 + i].c_str(), &end);
      if (end == fields[2 + i].c_str() || *end != '\0' || !std::isfinite(v) || v < -1e5 || v > 1e5)
        return fail("coordinate " + std::to_string(i + 1) + " is not a number: '" + fields[2 + i] + "'");
      a.quad[i / 2][i % 2] = static_cast<float>(v);
    }
    AnnotatedImage& image = by_name[fields[0]];
    image.name = fields[0];
    image.annotations.push_back(a);
  }
  // Images without markings have no rows; they are found by listing images/.
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(dir + "/images", ec)) {
    const std::string name = entry.path().filename().string();
    const std::string ext = entry.path().extension().string();
    if (ext != ".png" && ext != ".jpg" && ext != ".jpeg") continue;
    if (by_name.find(name) == by_name.end()) by_name[name].name = name;
  }
  if (ec) {
    error = dir + "/images: " + ec.message();
    return false;
  }
  images.clear();
  for (auto& [name, image] : by_name) images.push_back(std::move(image));
  return true;
}

bool read_drive_annotations(const std::string& dir, int step, std::vector<AnnotatedImage>& images,
                            std::string& error) {
  // Frames without visible markings count too (false detections): those
  // the drive has, up to the last with one.
  long drive_frames = 0;
  if (!count_drive_frames(dir, drive_frames, error)) return false;
  CsvReader csv(dir + "/visible.csv", kMaxDriveFileBytes);
  if (!csv.read_header("frame,id,class,x1", "frame,id,class,x1,y1,...,x4,y4", error)) return false;
  std::map<long, AnnotatedImage> by_frame;
  long last_frame = -1;
  std::vector<std::string> fields;
  while (csv.next(fields)) {
    const auto fail = [&](const std::string& what) { return csv.fail(what, error); };
    if (fields.size() != 11) return fail("expected 11 fields, found " + std::to_string(fields.size()));
    char* end = nullptr;
    const long frame = std::strtol(fields[0].c_str(), &end, 10);
    if (end == fields[0].c_str() || *end != '\0' || frame < 0 || frame > 100000000)
      return fail("bad frame number '" + fields[0] + "'");
    if (frame >= drive_frames)
      return fail("frame " + fields[0] + " is beyond the drive's " + std::to_string(drive_frames) +
                  " frames (frames.csv)");
    last_frame = std::max(last_frame, frame);
    if (frame % step != 0) continue;
    Annotation a;
    a.label = fields[2];
    for (int i = 0; i < 8; ++i) {
      const double v = std::strtod(fields[3 + i].c_str(), &end);
      if (end == fields[3 + i].c_str() || *end != '\0' || !std::isfinite(v) || v < -1e5 || v > 1e5)
        return fail("coordinate " + std::to_string(i + 1) + " is not a number: '" + fields[3 + i] + "'");
      a.quad[i / 2][i % 2] = static_cast<float>(v);
    }
    AnnotatedImage& image = by_frame[frame];
    image.name = std::to_string(frame);
    image.annotations.push_back(a);
  }
  for (long f = 0; f <= last_frame; f += step)
    if (by_frame.find(f) == by_frame.end()) by_frame[f].name = std::to_string(f);
  images.clear();
  for (auto& [frame, image] : by_frame) images.push_back(std::move(image));
  return true;
}

}  // namespace

Result<std::vector<AnnotatedImage>> load_annotations(const std::string& dir) {
  std::vector<AnnotatedImage> images;
  std::string problem;
  if (!read_annotations(dir, images, problem)) return error(problem);
  return images;
}

Result<std::vector<AnnotatedImage>> load_drive_annotations(const std::string& dir, int step) {
  std::vector<AnnotatedImage> images;
  std::string problem;
  if (!read_drive_annotations(dir, step, images, problem)) return error(problem);
  return images;
}

int clip_of(const std::string& name) {
  const auto underscore = name.rfind('_');
  const std::size_t start = underscore == std::string::npos ? 0 : underscore + 1;
  std::size_t end = start;
  while (end < name.size() && std::isdigit(static_cast<unsigned char>(name[end]))) ++end;
  if (end == start) return -1;
  const long number = std::strtol(name.substr(start, end - start).c_str(), nullptr, 10);
  return number >= 1 ? static_cast<int>((number - 1) / 60) : 0;
}

}  // namespace markloop::perception::train
