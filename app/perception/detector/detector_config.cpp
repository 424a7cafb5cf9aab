#include "app/perception/detector/detector_config.hpp"

#include <exception>
#include <optional>
#include <string>

#include <opencv2/core/persistence.hpp>

#include "app/perception/storage_file.hpp"

namespace markloop::perception {
namespace {

// The detector_* settings that are numbers within a range.
struct RangedKey {
  const char* name;
  float DetectorConfig::*value;
  float min, max;
};

// The road region's keys go through BirdsEyeRegion: pointers to its members.
struct RegionKey {
  const char* name;
  float BirdsEyeRegion::*value;
  float min, max;
};

constexpr RegionKey kRegionKeys[] = {
    {"detector_x_near_m", &BirdsEyeRegion::x_near_m, 0.0f, 100.0f},
    {"detector_x_far_m", &BirdsEyeRegion::x_far_m, 0.5f, 200.0f},
    {"detector_y_left_m", &BirdsEyeRegion::y_left_m, -50.0f, 50.0f},
    {"detector_y_right_m", &BirdsEyeRegion::y_right_m, -50.0f, 50.0f},
    {"detector_x_step_m", &BirdsEyeRegion::x_step_m, 0.005f, 1.0f},
    {"detector_y_step_m", &BirdsEyeRegion::y_step_m, 0.005f, 1.0f},
};

const RangedKey kRangedKeys[] = {
    {"detector_guard_m", &DetectorConfig::guard_m, 0.0f, 5.0f},
    {"detector_local_window_m", &DetectorConfig::local_window_m, 0.1f, 20.0f},
    {"detector_min_score", &DetectorConfig::min_score, 0.0f, 1.0f},
    {"detector_horizon_gain", &DetectorConfig::horizon_gain, 0.001f, 1.0f},
    {"detector_cnn_share", &DetectorConfig::cnn_share, 0.0f, 1.0f},
    {"detector_skip_networks_at", &DetectorConfig::skip_networks_at, 0.0f, 2.0f},
    {"detector_turned_min_score", &DetectorConfig::turned_min_score, 0.0f, 2.0f},
    {"detector_min_view_spread", &DetectorConfig::min_view_spread, 0.0f, 64.0f},
    {"detector_min_view_coherence", &DetectorConfig::min_view_coherence, 0.0f, 1.0f},
};

// The number under `name`, when present, into `value`.
Status read_ranged(const cv::FileStorage& fs, const std::string& path, const char* name, float min, float max,
                   float& value) {
  const cv::FileNode node = fs[name];
  if (node.empty()) return {};
  if (!node.isReal() && !node.isInt()) return error(path + ": " + name + " must be a number");
  const double v = static_cast<double>(node);
  if (!(v >= min && v <= max))
    return error(path + ": " + name + " = " + std::to_string(v) + " out of range " + std::to_string(min) +
                 ".." + std::to_string(max));
  value = static_cast<float>(v);
  return {};
}

Status read_numbers(const cv::FileStorage& fs, const std::string& path, DetectorConfig& c) {
  for (const RegionKey& key : kRegionKeys)
    if (Status read = read_ranged(fs, path, key.name, key.min, key.max, c.region.*key.value); !read)
      return read;
  for (const RangedKey& key : kRangedKeys)
    if (Status read = read_ranged(fs, path, key.name, key.min, key.max, c.*key.value); !read) return read;
  return {};
}

Status read_switch(const cv::FileStorage& fs, const std::string& path, const char* name, bool& value) {
  const cv::FileNode node = fs[name];
  if (node.empty()) return {};
  if (!node.isInt() || (static_cast<int>(node) != 0 && static_cast<int>(node) != 1))
    return error(path + ": " + name + " must be 0 or 1");
  value = static_cast<int>(node) == 1;
  return {};
}

Status read_side_crosswalks(const cv::FileStorage& fs, const std::string& path, DetectorConfig& c) {
  return read_switch(fs, path, "detector_side_crosswalks", c.side_crosswalks);
}

Status read_horizon(const cv::FileStorage& fs, const std::string& path, DetectorConfig& c) {
  if (Status read = read_switch(fs, path, "detector_horizon_from_lanes", c.horizon_from_lanes); !read)
    return read;
  if (Status read =
          read_switch(fs, path, "detector_hidden_below_follows_horizon", c.hidden_below_follows_horizon);
      !read)
    return read;
  const cv::FileNode max_shift = fs["detector_horizon_max_shift_px"];
  if (max_shift.empty()) return {};
  if (!max_shift.isInt() || static_cast<int>(max_shift) < 0 || static_cast<int>(max_shift) > 200)
    return error(path + ": detector_horizon_max_shift_px must be a whole number 0..200");
  c.horizon_max_shift_px = static_cast<int>(max_shift);
  return {};
}

// [column, row, column, row, ...], columns increasing: the image outline
// below which the camera sees the car. The error says what is wrong with it.
Result<ImageOutline> read_outline(const cv::FileNode& node) {
  if (!node.isSeq() || node.size() < 2 || node.size() % 2 != 0 || node.size() > 2 * ImageOutline::kMaxPoints)
    return error("must be a list of 1.." + std::to_string(ImageOutline::kMaxPoints) +
                 " points as [column, row, column, row, ...]");
  ImageOutline read;
  for (std::size_t i = 0; i < node.size(); ++i) {
    const cv::FileNode value = node[static_cast<int>(i)];
    if (!value.isReal() && !value.isInt()) return error("item " + std::to_string(i + 1) + " is not a number");
    read.points[i / 2][i % 2] = static_cast<float>(static_cast<double>(value));
  }
  read.count = node.size() / 2;
  for (std::size_t i = 1; i < read.count; ++i)
    if (!(read.points[i][0] > read.points[i - 1][0]))
      return error("point " + std::to_string(i + 1) + ": columns must increase left to right");
  return read;
}

// The bonnet: below an image row, or below an outline (which wins).
Status read_hidden_below(const cv::FileStorage& fs, const std::string& path, DetectorConfig& c) {
  const cv::FileNode rows = fs["detector_ignore_image_rows_from"];
  if (!rows.empty()) {
    if (!rows.isInt()) return error(path + ": detector_ignore_image_rows_from must be a whole number");
    c.hidden_below = {};
    c.hidden_below.points[0] = {0.0f, static_cast<float>(static_cast<int>(rows))};
    c.hidden_below.count = 1;
  }
  const cv::FileNode outline = fs["detector_hidden_below"];
  if (outline.empty()) return {};
  Result<ImageOutline> read = read_outline(outline);
  if (!read) return error(path + ": detector_hidden_below " + read.message());
  c.hidden_below = *read;
  return {};
}

Status check_region(const std::string& path, const BirdsEyeRegion& region) {
  if (!(region.x_far_m > region.x_near_m + region.x_step_m) ||
      !(region.y_left_m > region.y_right_m + region.y_step_m))
    return error(path + ": detector region is empty (need x_far > x_near, y_left > y_right)");
  const double cells = (region.x_far_m - region.x_near_m) / region.x_step_m *
                       (region.y_left_m - region.y_right_m) / region.y_step_m;
  if (cells > 4.0e6)
    return error(path + ": detector region has " + std::to_string(cells) + " bird's-eye pixels; at most 4e6");
  return {};
}

Result<DetectorConfig> read_detector_config(const cv::FileStorage& fs, const std::string& path,
                                            DetectorConfig c) {
  for (Status (*read)(const cv::FileStorage&, const std::string&, DetectorConfig&) :
       {read_numbers, read_side_crosswalks, read_horizon, read_hidden_below})
    if (Status status = read(fs, path, c); !status) return status.error();
  if (Status region = check_region(path, c.region); !region) return region.error();
  return c;
}

}  // namespace

Result<DetectorConfig> load_detector_config(const std::string& path, const DetectorConfig& defaults) {
  // FileStorage reports syntax errors by throwing cv::Exception; they stop
  // here, at start-up, never in the loop.
  try {
    Result<cv::FileStorage> storage = open_storage_file(path);
    if (!storage) return storage.error();
    return read_detector_config(*storage, path, defaults);
  } catch (const std::exception& e) {
    return error(path + ": " + e.what());
  }
}

}  // namespace markloop::perception
