#include "app/perception/detector/part_labeller.hpp"

#include <algorithm>
#include <cmath>

#include "app/perception/detector/paint_mask.hpp"

namespace markloop::perception {

PartLabeller::PartLabeller(const PartConfig& config, float stroke_max_length_m, const BirdsEyeRegion& region,
                           int rows, int cols)
    : config_(config),
      stroke_max_length_m_(stroke_max_length_m),
      x_step_m_(region.x_step_m),
      y_step_m_(region.y_step_m) {
  min_part_area_px_ = std::max(
      1, static_cast<int>(std::lround(config.min_part_area_m2 / (region.x_step_m * region.y_step_m))));
  const std::size_t pixels = static_cast<std::size_t>(rows) * cols;
  pixel_labels_.assign(pixels, -1);
  // 8-connected labelling gives at most one provisional label per two pixels
  // of a row, plus one.
  const std::size_t max_labels = static_cast<std::size_t>(rows) * ((cols + 1) / 2 + 1);
  parent_.assign(max_labels, 0);
  label_box_.assign(max_labels, Part{});
  label_moments_.assign(max_labels, Moments{});
  fill_reached_.assign(pixels, 0);
  fill_queue_.assign(pixels, 0);
  parts_.assign(kMaxParts, Part{});
}

std::size_t PartLabeller::label(const cv::Mat& mask, LaneHorizon* lanes, DetectorCounters& counters) {
  const int labels = label_pixels(mask);
  merge_into_roots(labels);
  keep_parts(mask, labels, lanes, counters);
  counters.parts += part_count_;
  return part_count_;
}

int PartLabeller::label_pixels(const cv::Mat& mask) {
  int next = 0;
  for (int r = 0; r < mask.rows; ++r) label_row(mask, r, next);
  return next;
}

void PartLabeller::label_row(const cv::Mat& mask, int r, int& next) {
  const int cols = mask.cols;
  const int max_labels = static_cast<int>(parent_.size());
  const std::uint8_t* m = mask.ptr<std::uint8_t>(r);
  std::int32_t* parent = parent_.data();
  std::int32_t* row = pixel_labels_.data() + static_cast<std::size_t>(r) * cols;
  const std::int32_t* up = r > 0 ? row - cols : nullptr;
  for (int c = 0; c < cols; ++c) {
    if (const int painted = next_painted(m, c, cols); painted != c) {
      std::fill(row + c, row + painted, -1);
      if (painted == cols) break;
      c = painted;
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
      label_box_[label] = Part{c, r, c, r, 0, 0, false};
      label_moments_[label] = Moments{};
    }
    row[c] = label;
    add_pixel(label, r, c);
  }
}

void PartLabeller::add_pixel(int label, int r, int c) {
  Part& box = label_box_[label];
  box.col0 = std::min(box.col0, c);
  box.col1 = std::max(box.col1, c);
  box.row1 = r;  // rows only grow
  ++box.area;
  Moments& sums = label_moments_[label];
  sums.row += r;
  sums.col += c;
  sums.row_row += static_cast<std::int64_t>(r) * r;
  sums.col_col += static_cast<std::int64_t>(c) * c;
  sums.row_col += static_cast<std::int64_t>(r) * c;
}

void PartLabeller::merge_into_roots(int labels) {
  std::int32_t* parent = parent_.data();
  for (int label = 0; label < labels; ++label) {
    const int root = find_root(parent, label);
    if (root == label) continue;
    Part& into = label_box_[root];
    const Part& from = label_box_[label];
    grow_box(into, from);
    into.area += from.area;
    Moments& sums = label_moments_[root];
    const Moments& more = label_moments_[label];
    sums.row += more.row;
    sums.col += more.col;
    sums.row_row += more.row_row;
    sums.col_col += more.col_col;
    sums.row_col += more.row_col;
  }
}

void PartLabeller::keep_parts(const cv::Mat& mask, int labels, LaneHorizon* lanes,
                              DetectorCounters& counters) {
  part_count_ = 0;
  stroke_count_ = 0;
  for (int label = 0; label < labels; ++label) {
    if (parent_[label] != label) continue;
    const Part& box = label_box_[label];
    if (box.area < min_part_area_px_) continue;
    const PartAxis part_axis = axis(box, label_moments_[label]);
    if (lanes != nullptr) lanes->note(part_axis);
    if (set_apart_as_line(mask, label, part_axis, counters)) continue;
    const float length = static_cast<float>(rows_of(box)) * x_step_m_;
    const float width = static_cast<float>(cols_of(box)) * y_step_m_;
    if (length > config_.max_marking_length_m || width > config_.max_marking_width_m) {
      ++counters.oversize;
      continue;
    }
    if (part_count_ == kMaxParts) {
      ++counters.parts_dropped;
      continue;
    }
    parts_[part_count_] = box;
    parts_[part_count_++].thin = part_axis.width_m <= config_.line_max_width_m;
  }
}

bool PartLabeller::set_apart_as_line(const cv::Mat& mask, int label, const PartAxis& part_axis,
                                     DetectorCounters& counters) {
  const Part& box = label_box_[label];
  const float length = static_cast<float>(rows_of(box)) * x_step_m_;
  const float width = static_cast<float>(cols_of(box)) * y_step_m_;
  const float fill = static_cast<float>(box.area) / static_cast<float>(rows_of(box) * cols_of(box));
  // Lines at an angle to the view's columns (a bend, a road crossed
  // obliquely) are thin along their own axis, not their box's.
  const bool oblique_line =
      part_axis.width_m <= config_.line_max_width_m && part_axis.length_m >= config_.line_min_length_m;
  // A sparse part is a line or kerb unless it is a closed outline.
  const bool sparse = width >= config_.sparse_min_size_m && length >= config_.sparse_min_size_m &&
                      fill < config_.sparse_max_fill;
  const bool straight_line = width <= config_.line_max_width_m && length >= config_.line_min_length_m;
  if (!(straight_line || oblique_line || (sparse && !encloses_road(mask, label, box)))) return false;
  ++counters.lane_lines;
  if ((straight_line || oblique_line) && length <= stroke_max_length_m_) {
    if (stroke_count_ < kMaxStrokes)
      strokes_[stroke_count_++] = box;
    else
      ++counters.strokes_dropped;
  }
  return true;
}

PartAxis PartLabeller::axis(const Part& box, const Moments& sums) const {
  const double n = box.area;
  const double mean_row = static_cast<double>(sums.row) / n;
  const double mean_col = static_cast<double>(sums.col) / n;
  // Second moments in metres, along the road (rows) and across it (columns).
  const double xs = x_step_m_, ys = y_step_m_;
  const double along = (static_cast<double>(sums.row_row) / n - mean_row * mean_row) * xs * xs;
  const double across = (static_cast<double>(sums.col_col) / n - mean_col * mean_col) * ys * ys;
  const double both = (static_cast<double>(sums.row_col) / n - mean_row * mean_col) * xs * ys;
  const double half_gap = std::sqrt(0.25 * (along - across) * (along - across) + both * both);
  const double major = 0.5 * (along + across) + half_gap;
  const double minor = std::max(0.0, 0.5 * (along + across) - half_gap);
  // A uniform bar of length L has a variance of L^2 / 12 along it.
  return {mean_row, mean_col, std::sqrt(12.0 * major), std::sqrt(12.0 * minor),
          0.5 * std::atan2(2.0 * both, along - across)};
}

bool PartLabeller::encloses_road(const cv::Mat& mask, int label, const Part& box) {
  // Road inside the outline is what the box's border cannot reach without
  // crossing this part's paint (4-connected, as the paint is 8-connected).
  constexpr float kMinEnclosedM2 = 0.1f;
  const int cols = mask.cols;
  const int min_enclosed =
      std::max(1, static_cast<int>(std::lround(kMinEnclosedM2 / (x_step_m_ * y_step_m_))));
  std::int32_t* parent = parent_.data();
  const std::int32_t* labels = pixel_labels_.data();
  const auto is_paint = [&](int index) {
    return labels[index] >= 0 && find_root(parent, labels[index]) == label;
  };
  std::size_t head = 0, tail = 0;
  const auto reach = [&](int row, int col) {
    const int index = row * cols + col;
    if (fill_reached_[static_cast<std::size_t>(index)] != 0 || is_paint(index)) return;
    fill_reached_[static_cast<std::size_t>(index)] = 1;
    fill_queue_[tail++] = index;
  };
  for (int row = box.row0; row <= box.row1; ++row)
    std::fill_n(fill_reached_.begin() + static_cast<std::ptrdiff_t>(row) * cols + box.col0, cols_of(box),
                std::uint8_t{0});
  for (int col = box.col0; col <= box.col1; ++col) {
    reach(box.row0, col);
    reach(box.row1, col);
  }
  for (int row = box.row0; row <= box.row1; ++row) {
    reach(row, box.col0);
    reach(row, box.col1);
  }
  while (head < tail) {
    const int index = fill_queue_[head++];
    const int row = index / cols, col = index % cols;
    if (row > box.row0) reach(row - 1, col);
    if (row < box.row1) reach(row + 1, col);
    if (col > box.col0) reach(row, col - 1);
    if (col < box.col1) reach(row, col + 1);
  }
  const int box_pixels = rows_of(box) * cols_of(box);
  const int enclosed = box_pixels - box.area - static_cast<int>(tail);
  return enclosed >= min_enclosed;
}

}  // namespace markloop::perception
