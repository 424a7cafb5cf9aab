#include "perception/marking_detector.hpp"

#include <algorithm>
#include <cmath>
#include <exception>

#include <opencv2/core/persistence.hpp>

#include "perception/marking_classifier.hpp"

namespace markloop::perception {
namespace {

int find_root(std::int32_t* parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];  // path halving
    i = parent[i];
  }
  return i;
}

void unite(std::int32_t* parent, int a, int b) {
  a = find_root(parent, a);
  b = find_root(parent, b);
  if (a < b)
    parent[b] = a;
  else if (b < a)
    parent[a] = b;
}

int odd_at_least_3(float value) {
  const int n = std::max(3, static_cast<int>(std::lround(value)));
  return n | 1;
}

// [column, row, column, row, ...], columns increasing: the image outline
// below which the camera sees the car.
bool read_outline(const cv::FileNode& node, ImageOutline& outline, std::string& error) {
  if (!node.isSeq() || node.size() < 2 || node.size() % 2 != 0 ||
      node.size() > 2 * ImageOutline::kMaxPoints) {
    error = "must be a list of 1.." + std::to_string(ImageOutline::kMaxPoints) +
            " points as [column, row, column, row, ...]";
    return false;
  }
  ImageOutline read;
  for (std::size_t i = 0; i < node.size(); ++i) {
    const cv::FileNode value = node[static_cast<int>(i)];
    if (!value.isReal() && !value.isInt()) {
      error = "item " + std::to_string(i + 1) + " is not a number";
      return false;
    }
    read.points[i / 2][i % 2] = static_cast<float>(static_cast<double>(value));
  }
  read.count = node.size() / 2;
  for (std::size_t i = 1; i < read.count; ++i)
    if (!(read.points[i][0] > read.points[i - 1][0])) {
      error = "point " + std::to_string(i + 1) + ": columns must increase left to right";
      return false;
    }
  outline = read;
  return true;
}

}  // namespace

MarkingDetector::MarkingDetector(const CameraModel& camera, const DetectorConfig& config)
    : camera_(camera),
      config_(config),
      birdseye_(camera, config.region, config.hidden_below),
      model_(config.model != nullptr ? config.model : &builtin_marking_model()) {
  const int rows = birdseye_.rows(), cols = birdseye_.cols();
  const auto& region = config.region;
  window_cols_ = odd_at_least_3(config.local_window_m / region.y_step_m);
  window_rows_ = odd_at_least_3(config.local_window_m / region.x_step_m);
  min_part_area_px_ = std::max(
      1, static_cast<int>(std::lround(config.min_part_area_m2 / (region.x_step_m * region.y_step_m))));
  bev_.create(rows, cols, CV_8UC1);
  bev_.setTo(0);
  mask_.create(rows, cols, CV_8UC1);
  mask_.setTo(0);
  integral_.create(rows + 1, cols + 1, CV_32SC1);
  integral_.setTo(0);
  // Valid-pixel counts never change: integrate them once.
  valid_integral_.create(rows + 1, cols + 1, CV_32SC1);
  valid_integral_.setTo(0);
  const cv::Mat& valid = birdseye_.valid();
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* v = valid.ptr<std::uint8_t>(r);
    const std::int32_t* above = valid_integral_.ptr<std::int32_t>(r);
    std::int32_t* out = valid_integral_.ptr<std::int32_t>(r + 1);
    std::int32_t line = 0;
    for (int c = 0; c < cols; ++c) {
      line += v[c] != 0 ? 1 : 0;
      out[c + 1] = above[c + 1] + line;
    }
  }
  // Pixels on the view's border or next to (or on) one the camera does not
  // see: paint there may go on beyond what is seen.
  at_edge_.create(rows, cols, CV_8UC1);
  for (int r = 0; r < rows; ++r) {
    std::uint8_t* out = at_edge_.ptr<std::uint8_t>(r);
    for (int c = 0; c < cols; ++c) {
      bool edge = r == 0 || c == 0 || r == rows - 1 || c == cols - 1;
      for (int rr = std::max(0, r - 1); rr <= std::min(rows - 1, r + 1); ++rr)
        for (int cc = std::max(0, c - 1); cc <= std::min(cols - 1, c + 1); ++cc)
          edge = edge || valid.ptr<std::uint8_t>(rr)[cc] == 0;
      out[c] = edge ? 1 : 0;
    }
  }
  const std::size_t pixels = static_cast<std::size_t>(rows) * cols;
  pixel_labels_.assign(pixels, -1);
  run_above_.assign(pixels, 0);
  run_below_.assign(pixels, 0);
  // 8-connected labelling gives at most one provisional label per two pixels
  // of a row, plus one.
  const std::size_t max_labels = static_cast<std::size_t>(rows) * ((cols + 1) / 2 + 1);
  parent_.assign(max_labels, 0);
  label_box_.assign(max_labels, Part{});
  parts_.assign(kMaxParts, Part{});
  group_parent_.assign(kMaxParts, 0);
  group_candidate_.assign(kMaxParts, -1);
}

std::span<const Detection> MarkingDetector::detect(const cv::Mat& grey) {
  ++counters_.frames;
  detection_count_ = 0;
  candidate_count_ = 0;
  if (grey.type() != CV_8UC1 || grey.cols != camera_.width() || grey.rows != camera_.height() ||
      !model_is_usable(*model_)) {
    ++counters_.bad_frames;
    return {};
  }
  birdseye_.warp(grey, bev_);
  threshold();
  cut_line_junctions();
  const std::size_t part_count = label_parts();
  group_parts(part_count);
  for (std::size_t i = 0; i < candidate_count_; ++i) classify(candidates_[i]);
  for (std::size_t i = 0; i < candidate_count_; ++i) {
    const Candidate& candidate = candidates_[i];
    if (candidate.predicted == kRejectClass) {
      ++counters_.rejected;
      continue;
    }
    // Parts too large to group (a railway X) are never grouped with the
    // pieces inside them; reported, a piece would be a second landmark.
    if (is_piece_of_larger(candidates(), i)) {
      ++counters_.pieces;
      continue;
    }
    if (candidate.clipped && !config_.report_clipped) {
      ++counters_.clipped;
      continue;
    }
    if (candidate.score < config_.min_score) {
      ++counters_.low_score;
      continue;
    }
    if (detection_count_ == kMaxDetections) {
      ++counters_.detections_dropped;
      continue;
    }
    Detection& d = detections_[detection_count_++];
    d.label = static_cast<Label>(candidate.predicted);
    d.score = candidate.score;
    locate(candidate, d);
    ++counters_.detections;
  }
  return {detections_.data(), detection_count_};
}

void MarkingDetector::threshold() {
  const int rows = bev_.rows, cols = bev_.cols;
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* in = bev_.ptr<std::uint8_t>(r);
    const std::int32_t* above = integral_.ptr<std::int32_t>(r);
    std::int32_t* out = integral_.ptr<std::int32_t>(r + 1);
    std::int32_t line = 0;
    for (int c = 0; c < cols; ++c) {
      line += in[c];
      out[c + 1] = above[c + 1] + line;
    }
  }
  const int half_r = window_rows_ / 2, half_c = window_cols_ / 2;
  // Paint: value > mean + max(contrast, ratio * mean), in integers scaled by
  // the window's valid-pixel count and 256 (no division per pixel; window
  // sums stay below 2^31: 255 * 256 * count, count < 2^15).
  const std::int32_t ratio_q8 =
      static_cast<std::int32_t>(std::lround(config_.min_contrast_ratio * 256.0f));
  const std::int32_t contrast_q8 = config_.min_contrast * 256;
  const cv::Mat& valid = birdseye_.valid();
  for (int r = 0; r < rows; ++r) {
    const int r0 = std::max(0, r - half_r), r1 = std::min(rows, r + half_r + 1);
    const std::int32_t* sum_top = integral_.ptr<std::int32_t>(r0);
    const std::int32_t* sum_bottom = integral_.ptr<std::int32_t>(r1);
    const std::int32_t* count_top = valid_integral_.ptr<std::int32_t>(r0);
    const std::int32_t* count_bottom = valid_integral_.ptr<std::int32_t>(r1);
    const std::uint8_t* in = bev_.ptr<std::uint8_t>(r);
    const std::uint8_t* v = valid.ptr<std::uint8_t>(r);
    std::uint8_t* out = mask_.ptr<std::uint8_t>(r);
    const auto decide = [&](int c, int c0, int c1) {
      const std::int32_t count = count_bottom[c1] - count_bottom[c0] - count_top[c1] + count_top[c0];
      const std::int32_t sum = sum_bottom[c1] - sum_bottom[c0] - sum_top[c1] + sum_top[c0];
      const std::int32_t margin = std::max(contrast_q8 * count, ratio_q8 * sum);
      // Bitwise, not short-circuit: no branch, so the loop vectorises.
      const int paint = static_cast<int>(v[c] != 0) & static_cast<int>(in[c] * count * 256 > sum * 256 + margin);
      out[c] = static_cast<std::uint8_t>(paint * 255);
    };
    // Where the window lies wholly inside the row its bounds are fixed
    // offsets, and the loop vectorises; the borders clamp them.
    const int inner_begin = std::min(cols, half_c), inner_end = std::max(inner_begin, cols - half_c);
    for (int c = 0; c < inner_begin; ++c) decide(c, 0, std::min(cols, c + half_c + 1));
    for (int c = inner_begin; c < inner_end; ++c) decide(c, c - half_c, c + half_c + 1);
    for (int c = inner_end; c < cols; ++c) decide(c, std::max(0, c - half_c), cols);
  }
}

void MarkingDetector::cut_line_junctions() {
  const int rows = mask_.rows, cols = mask_.cols;
  const int along = std::max(2, static_cast<int>(std::lround(config_.junction_along_m / config_.region.x_step_m)));
  const int across = std::max(2, static_cast<int>(std::lround(config_.junction_across_m / config_.region.y_step_m)));
  // Vertical run lengths, saturating (int16): from above, then from below.
  // `previous` is the run one row back (none for the first row); written
  // without branches so that the loop vectorises.
  const auto extend_runs = [cols](const std::uint8_t* m, const std::int16_t* previous,
                                  std::int16_t* here) {
    if (previous == nullptr) {
      for (int c = 0; c < cols; ++c) here[c] = static_cast<std::int16_t>(m[c] != 0);
      return;
    }
    for (int c = 0; c < cols; ++c)
      here[c] = static_cast<std::int16_t>((m[c] != 0) * std::min(previous[c] + 1, 30000));
  };
  for (int r = 0; r < rows; ++r) {
    std::int16_t* here = run_above_.data() + static_cast<std::size_t>(r) * cols;
    extend_runs(mask_.ptr<std::uint8_t>(r), r > 0 ? here - cols : nullptr, here);
  }
  for (int r = rows - 1; r >= 0; --r) {
    std::int16_t* here = run_below_.data() + static_cast<std::size_t>(r) * cols;
    extend_runs(mask_.ptr<std::uint8_t>(r), r + 1 < rows ? here + cols : nullptr, here);
  }
  // Junction pixels: on a long vertical run and on a long horizontal run.
  // They are marked in run_below_ (as -1) first and cleared with their
  // 8-neighbours afterwards, so that no diagonal contact survives. Where the
  // paint across is a long bar (a stop line, not an arrow's head), they are
  // marked -2 and the cut reaches `margin` rows further along the line: a
  // slanted or blurred edge of the bar would otherwise join them again.
  const int long_bar = std::max(
      across, static_cast<int>(std::lround(config_.junction_long_bar_m / config_.region.y_step_m)));
  bool any = false;
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* m = mask_.ptr<std::uint8_t>(r);
    const std::int16_t* above = run_above_.data() + static_cast<std::size_t>(r) * cols;
    std::int16_t* below = run_below_.data() + static_cast<std::size_t>(r) * cols;
    int c = 0;
    while (c < cols) {
      if (m[c] == 0) {
        ++c;
        continue;
      }
      int end = c;
      while (end < cols && m[end] != 0) ++end;
      if (end - c >= across) {
        const std::int16_t mark = end - c >= long_bar ? -2 : -1;
        for (int k = c; k < end; ++k)
          if (above[k] + below[k] - 1 >= along) {
            below[k] = mark;
            any = true;
          }
      }
      c = end;
    }
  }
  if (!any) return;
  const int margin = std::max(
      1, static_cast<int>(std::lround(config_.junction_cut_margin_m / config_.region.x_step_m)));
  for (int r = 0; r < rows; ++r) {
    const std::int16_t* below = run_below_.data() + static_cast<std::size_t>(r) * cols;
    for (int c = 0; c < cols; ++c) {
      if (below[c] >= 0) continue;
      const int reach = below[c] == -2 ? margin : 1;
      for (int rr = std::max(0, r - reach); rr <= std::min(rows - 1, r + reach); ++rr) {
        std::uint8_t* m = mask_.ptr<std::uint8_t>(rr);
        for (int cc = std::max(0, c - 1); cc <= std::min(cols - 1, c + 1); ++cc) m[cc] = 0;
      }
    }
  }
}

std::size_t MarkingDetector::label_parts() {
  const int rows = mask_.rows, cols = mask_.cols;
  std::int32_t* labels = pixel_labels_.data();
  std::int32_t* parent = parent_.data();
  int next = 0;
  const int max_labels = static_cast<int>(parent_.size());
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* m = mask_.ptr<std::uint8_t>(r);
    std::int32_t* row = labels + static_cast<std::size_t>(r) * cols;
    const std::int32_t* up = r > 0 ? row - cols : nullptr;
    for (int c = 0; c < cols; ++c) {
      if (m[c] == 0) {
        row[c] = -1;
        continue;
      }
      int label = -1;
      const auto join = [&](std::int32_t other) {
        if (other < 0) return;
        if (label < 0)
          label = other;
        else if (other != label)
          unite(parent, label, other);
      };
      if (c > 0) join(row[c - 1]);
      if (up != nullptr) {
        if (c > 0) join(up[c - 1]);
        join(up[c]);
        if (c + 1 < cols) join(up[c + 1]);
      }
      if (label < 0) {
        // Cannot overflow (see the constructor), but never index past the end.
        if (next == max_labels) {
          row[c] = -1;
          continue;
        }
        label = next++;
        parent[label] = label;
        label_box_[label] = Part{c, r, c, r, 0, 0};
      }
      row[c] = label;
      Part& box = label_box_[label];
      box.col0 = std::min(box.col0, c);
      box.col1 = std::max(box.col1, c);
      box.row1 = r;  // rows only grow
      ++box.area;
    }
  }
  // Merge each provisional label's box into its root's.
  for (int label = 0; label < next; ++label) {
    const int root = find_root(parent, label);
    if (root == label) continue;
    Part& into = label_box_[root];
    const Part& from = label_box_[label];
    into.col0 = std::min(into.col0, from.col0);
    into.col1 = std::max(into.col1, from.col1);
    into.row0 = std::min(into.row0, from.row0);
    into.row1 = std::max(into.row1, from.row1);
    into.area += from.area;
  }
  const auto& region = config_.region;
  std::size_t count = 0;
  for (int label = 0; label < next; ++label) {
    if (parent[label] != label) continue;
    const Part& box = label_box_[label];
    if (box.area < min_part_area_px_) continue;
    const float length = static_cast<float>(box.row1 - box.row0 + 1) * region.x_step_m;
    const float width = static_cast<float>(box.col1 - box.col0 + 1) * region.y_step_m;
    const float fill = static_cast<float>(box.area) /
                       static_cast<float>((box.row1 - box.row0 + 1) * (box.col1 - box.col0 + 1));
    if ((width <= config_.line_max_width_m && length >= config_.line_min_length_m) ||
        (width >= config_.sparse_min_size_m && length >= config_.sparse_min_size_m &&
         fill < config_.sparse_max_fill)) {
      ++counters_.lane_lines;
      continue;
    }
    if (length > config_.max_marking_length_m || width > config_.max_marking_width_m) {
      ++counters_.oversize;
      continue;
    }
    if (count == kMaxParts) {
      ++counters_.parts_dropped;
      continue;
    }
    parts_[count++] = box;
  }
  counters_.parts += count;
  return count;
}

void MarkingDetector::group_parts(std::size_t part_count) {
  const auto& region = config_.region;
  const int gap_cols = static_cast<int>(std::lround(config_.group_gap_across_m / region.y_step_m));
  const int gap_rows = static_cast<int>(std::lround(config_.group_gap_along_m / region.x_step_m));
  const int max_cols = static_cast<int>(std::lround(config_.group_max_part_m / region.y_step_m));
  const int max_rows = static_cast<int>(std::lround(config_.group_max_part_m / region.x_step_m));
  const int bar_min_cols = static_cast<int>(std::lround(config_.bar_min_width_m / region.y_step_m));
  const int bar_max_rows = static_cast<int>(std::lround(config_.bar_max_length_m / region.x_step_m));
  const auto groupable = [&](const Part& p) {
    const bool bar = p.col1 - p.col0 + 1 >= bar_min_cols && p.row1 - p.row0 + 1 <= bar_max_rows;
    return p.col1 - p.col0 < max_cols && p.row1 - p.row0 < max_rows && !bar;
  };
  std::int32_t* parent = group_parent_.data();
  for (std::size_t i = 0; i < part_count; ++i) parent[i] = static_cast<std::int32_t>(i);
  for (std::size_t i = 0; i < part_count; ++i) {
    const Part& a = parts_[i];
    if (!groupable(a)) continue;
    for (std::size_t j = i + 1; j < part_count; ++j) {
      const Part& b = parts_[j];
      if (!groupable(b)) continue;
      if (b.col0 > a.col1 + gap_cols || a.col0 > b.col1 + gap_cols) continue;
      if (b.row0 > a.row1 + gap_rows || a.row0 > b.row1 + gap_rows) continue;
      unite(parent, static_cast<int>(i), static_cast<int>(j));
    }
  }
  for (std::size_t i = 0; i < part_count; ++i) group_candidate_[i] = -1;
  for (std::size_t i = 0; i < part_count; ++i) {
    const int root = find_root(parent, static_cast<int>(i));
    const Part& p = parts_[i];
    std::int32_t& slot = group_candidate_[root];
    if (slot < 0) {
      if (candidate_count_ == kMaxCandidates) {
        ++counters_.candidates_dropped;
        continue;
      }
      slot = static_cast<std::int32_t>(candidate_count_++);
      Candidate& c = candidates_[slot];
      c.col0 = p.col0;
      c.row0 = p.row0;
      c.col1 = p.col1;
      c.row1 = p.row1;
      c.parts = 1;
      continue;
    }
    Candidate& c = candidates_[slot];
    c.col0 = std::min(c.col0, p.col0);
    c.row0 = std::min(c.row0, p.row0);
    c.col1 = std::max(c.col1, p.col1);
    c.row1 = std::max(c.row1, p.row1);
    ++c.parts;
  }
  // Groups grown too large are not markings (the edges of cars, shadows).
  std::size_t kept = 0;
  for (std::size_t i = 0; i < candidate_count_; ++i) {
    Candidate& c = candidates_[i];
    c.length_m = static_cast<float>(c.row1 - c.row0 + 1) * region.x_step_m;
    c.width_m = static_cast<float>(c.col1 - c.col0 + 1) * region.y_step_m;
    if (c.length_m > config_.max_marking_length_m || c.width_m > config_.max_marking_width_m) {
      ++counters_.oversize;
      continue;
    }
    c.clipped = touches_edge(c);
    candidates_[kept++] = c;
  }
  candidate_count_ = kept;
  counters_.candidates += kept;
}

bool is_piece_of_larger(std::span<const Candidate> candidates, std::size_t index) {
  const Candidate& c = candidates[index];
  for (std::size_t j = 0; j < candidates.size(); ++j) {
    const Candidate& outer = candidates[j];
    if (j == index || (outer.predicted != c.predicted && !outer.clipped)) continue;
    const bool inside = outer.col0 <= c.col0 && c.col1 <= outer.col1 && outer.row0 <= c.row0 &&
                        c.row1 <= outer.row1;
    const bool larger = (outer.col1 - outer.col0) * (outer.row1 - outer.row0) >
                        (c.col1 - c.col0) * (c.row1 - c.row0);
    if (inside && larger) return true;
  }
  return false;
}

bool MarkingDetector::touches_edge(const Candidate& c) const {
  // Paint of the box next to the edge of the view: the marking may go on
  // beyond it. The box alone would say so for every marking whose box
  // corner reaches into the unseen corners of the view.
  for (int row = c.row0; row <= c.row1; ++row) {
    const std::uint8_t* paint = mask_.ptr<std::uint8_t>(row);
    const std::uint8_t* edge = at_edge_.ptr<std::uint8_t>(row);
    int touching = 0;
    for (int col = c.col0; col <= c.col1; ++col) touching |= paint[col] & edge[col];
    if (touching != 0) return true;
  }
  return false;
}

void MarkingDetector::classify(Candidate& candidate) {
  const PatchBox box{candidate.col0,    candidate.row0,   candidate.col1, candidate.row1,
                     candidate.length_m, candidate.width_m, candidate.parts};
  compute_features(bev_, mask_, box, scratch_, candidate.features);
  std::array<float, kClassifierOutputs> probabilities;
  candidate.predicted = perception::classify(*model_, candidate.features, probabilities);
  candidate.score = probabilities[candidate.predicted];
}

void MarkingDetector::locate(const Candidate& candidate, Detection& out) const {
  const float far = birdseye_.ground_x(static_cast<float>(candidate.row0) - 0.5f);
  const float near = birdseye_.ground_x(static_cast<float>(candidate.row1) + 0.5f);
  const float left = birdseye_.ground_y(static_cast<float>(candidate.col0) - 0.5f);
  const float right = birdseye_.ground_y(static_cast<float>(candidate.col1) + 0.5f);
  // The dataset's corner order: near left, near right, far right, far left.
  const std::array<std::array<float, 2>, 4> corners = {
      {{near, left}, {near, right}, {far, right}, {far, left}}};
  for (std::size_t i = 0; i < 4; ++i) {
    Eigen::Vector2d pixel(-1.0, -1.0);
    camera_.ground_to_image({corners[i][0], corners[i][1]}, pixel);
    out.quad[i] = {static_cast<float>(pixel.x()), static_cast<float>(pixel.y())};
  }
  out.ground_x = 0.5f * (near + far);
  out.ground_y = 0.5f * (left + right);
}

bool load_detector_config(const std::string& path, DetectorConfig& config, std::string& error) {
  try {
    cv::FileStorage fs(path, cv::FileStorage::READ);
    if (!fs.isOpened()) {
      error = path + ": cannot open as an OpenCV YAML/XML file";
      return false;
    }
    DetectorConfig c = config;
    struct Key {
      const char* name;
      float* value;
      float min, max;
    };
    const Key keys[] = {
        {"detector_x_near_m", &c.region.x_near_m, 0.0f, 100.0f},
        {"detector_x_far_m", &c.region.x_far_m, 0.5f, 200.0f},
        {"detector_y_left_m", &c.region.y_left_m, -50.0f, 50.0f},
        {"detector_y_right_m", &c.region.y_right_m, -50.0f, 50.0f},
        {"detector_x_step_m", &c.region.x_step_m, 0.005f, 1.0f},
        {"detector_y_step_m", &c.region.y_step_m, 0.005f, 1.0f},
        {"detector_local_window_m", &c.local_window_m, 0.1f, 20.0f},
        {"detector_min_score", &c.min_score, 0.0f, 1.0f},
    };
    for (const Key& key : keys) {
      const cv::FileNode node = fs[key.name];
      if (node.empty()) continue;
      if (!node.isReal() && !node.isInt()) {
        error = path + ": " + key.name + " must be a number";
        return false;
      }
      const double v = static_cast<double>(node);
      if (!(v >= key.min && v <= key.max)) {
        error = path + ": " + key.name + " = " + std::to_string(v) + " out of range " +
                std::to_string(key.min) + ".." + std::to_string(key.max);
        return false;
      }
      *key.value = static_cast<float>(v);
    }
    const cv::FileNode rows = fs["detector_ignore_image_rows_from"];
    if (!rows.empty()) {
      if (!rows.isInt()) {
        error = path + ": detector_ignore_image_rows_from must be a whole number";
        return false;
      }
      c.hidden_below = {};
      c.hidden_below.points[0] = {0.0f, static_cast<float>(static_cast<int>(rows))};
      c.hidden_below.count = 1;
    }
    const cv::FileNode outline = fs["detector_hidden_below"];
    if (!outline.empty() && !read_outline(outline, c.hidden_below, error)) {
      error = path + ": detector_hidden_below " + error;
      return false;
    }
    if (!(c.region.x_far_m > c.region.x_near_m + c.region.x_step_m) ||
        !(c.region.y_left_m > c.region.y_right_m + c.region.y_step_m)) {
      error = path + ": detector region is empty (need x_far > x_near, y_left > y_right)";
      return false;
    }
    const double cells = (c.region.x_far_m - c.region.x_near_m) / c.region.x_step_m *
                         (c.region.y_left_m - c.region.y_right_m) / c.region.y_step_m;
    if (cells > 4.0e6) {
      error = path + ": detector region has " + std::to_string(cells) +
              " bird's-eye pixels; at most 4e6";
      return false;
    }
    config = c;
    return true;
  } catch (const std::exception& e) {
    error = path + ": " + e.what();
    return false;
  }
}

}  // namespace markloop::perception
