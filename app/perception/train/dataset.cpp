#include "perception/train/dataset.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

namespace markloop::perception::train {

bool load_annotations(const std::string& dir, std::vector<AnnotatedImage>& images,
                      std::string& error) {
  const std::string path = dir + "/annotations.csv";
  std::ifstream in(path);
  if (!in) {
    error = path + ": cannot open";
    return false;
  }
  std::string line;
  int line_number = 1;
  if (!std::getline(in, line) || line.rfind("image,label,x1,y1", 0) != 0) {
    error = path + ":1: header must be image,label,x1,y1,x2,y2,x3,y3,x4,y4";
    return false;
  }
  std::map<std::string, AnnotatedImage> by_name;
  while (std::getline(in, line)) {
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    std::vector<std::string> fields;
    std::stringstream ss(line);
    std::string field;
    while (std::getline(ss, field, ',')) fields.push_back(field);
    const auto fail = [&](const std::string& what) {
      error = path + ":" + std::to_string(line_number) + ": " + what;
      return false;
    };
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

bool load_drive_annotations(const std::string& dir, int step, std::vector<AnnotatedImage>& images,
                            std::string& error) {
  const std::string path = dir + "/visible.csv";
  std::ifstream in(path);
  if (!in) {
    error = path + ": cannot open";
    return false;
  }
  std::string line;
  int line_number = 1;
  if (!std::getline(in, line) || line.rfind("frame,id,class,x1", 0) != 0) {
    error = path + ":1: header must be frame,id,class,x1,y1,...,x4,y4";
    return false;
  }
  std::map<long, AnnotatedImage> by_frame;
  long last_frame = -1;
  while (std::getline(in, line)) {
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    std::vector<std::string> fields;
    std::stringstream ss(line);
    std::string field;
    while (std::getline(ss, field, ',')) fields.push_back(field);
    const auto fail = [&](const std::string& what) {
      error = path + ":" + std::to_string(line_number) + ": " + what;
      return false;
    };
    if (fields.size() != 11) return fail("expected 11 fields, found " + std::to_string(fields.size()));
    char* end = nullptr;
    const long frame = std::strtol(fields[0].c_str(), &end, 10);
    if (end == fields[0].c_str() || *end != '\0' || frame < 0 || frame > 100000000)
      return fail("bad frame number '" + fields[0] + "'");
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
  // Frames without visible markings count too (false detections).
  for (long f = 0; f <= last_frame; f += step)
    if (by_frame.find(f) == by_frame.end()) by_frame[f].name = std::to_string(f);
  images.clear();
  for (auto& [frame, image] : by_frame) images.push_back(std::move(image));
  return true;
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
