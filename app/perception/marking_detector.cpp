#include "app/perception/marking_detector.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <exception>

#include <opencv2/core/persistence.hpp>
#include <opencv2/imgproc.hpp>

#include "app/perception/marking_classifier.hpp"
#include "app/perception/storage_file.hpp"

namespace markloop::perception {
namespace {

// detect_still() warps an image again with the horizon where the last look
// put it, up to this many looks in all: the farther the view is from the
// true horizon, the more it bends the lines that measure it.
constexpr int kStillLooks = 3;
// Lines (and dashes) shorter than this on the road say too little about
// their direction to place the horizon.
constexpr double kMinHorizonLineM = 1.5;
// Edges of the view (at_edge_ bits). Near: the unseen lies below, on the
// bonnet or under the image (or the region's near end): markings leave the
// view there as the car drives on, seen whole before. Other: the far end,
// the region's sides and the image's sides.
constexpr std::uint8_t kNearEdge = 1;
constexpr std::uint8_t kOtherEdge = 2;

// Rows a box (part, stroke, candidate) spans, and rows two boxes share (0
// or less when they share none).
template <typename Box>
int rows_of(const Box& box) {
  return box.row1 - box.row0 + 1;
}
template <typename BoxA, typename BoxB>
int rows_shared(const BoxA& a, const BoxB& b) {
  return std::min(a.row1, b.row1) - std::max(a.row0, b.row0) + 1;
}

// Whether `value` is brighter than the mean of `count` pixels summing to
// `sum` by contrast_q8 / 256 grey levels or ratio_q8 / 256 of the mean,
// whichever is larger; in integers scaled by count and 256 (no division;
// 255 * 256 * count stays below 2^31 for count < 2^15). Branch-free, so
// the threshold's loop vectorises.
inline bool brighter_than_mean(std::int32_t value, std::int32_t sum, std::int32_t count,
                               std::int32_t contrast_q8, std::int32_t ratio_q8) {
  const std::int32_t margin = std::max(contrast_q8 * count, ratio_q8 * sum);
  return value * count * 256 > sum * 256 + margin;
}

// The first column from c on with paint in row m, or cols: paint is sparse,
// so unpainted stretches are skipped eight bytes at a time.
int next_painted(const std::uint8_t* m, int c, int cols) {
  for (std::uint64_t eight = 0; c + 8 <= cols; c += 8) {
    std::memcpy(&eight, m + c, sizeof eight);
    if (eight != 0) break;
  }
  while (c < cols && m[c] == 0) ++c;
  return c;
}

int find_root(std::int32_t* parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];  // path halving
    i = parent[i];
  }
  return i;
}

// Grows `into` to cover `from` (parts' and candidates' boxes alike).
template <typename Into, typename From>
void grow_box(Into& into, const From& from) {
  into.col0 = std::min(into.col0, from.col0);
  into.col1 = std::max(into.col1, from.col1);
  into.row0 = std::min(into.row0, from.row0);
  into.row1 = std::max(into.row1, from.row1);
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

// The region the view covers: `region` and the guard band beyond its far
// end and sides, whole pixels wide, so that the pixels over `region` sample
// the same ground points with or without it.
BirdsEyeRegion with_guard_band(BirdsEyeRegion region, float guard_m) {
  const float along = std::ceil(guard_m / region.x_step_m - 1e-3f) * region.x_step_m;
  const float across = std::ceil(guard_m / region.y_step_m - 1e-3f) * region.y_step_m;
  region.x_far_m += along;
  region.y_left_m += across;
  region.y_right_m -= across;
  return region;
}

}  // namespace

MarkingDetector::MarkingDetector(const CameraModel& camera, const DetectorConfig& config)
    : camera_(camera),
      config_(config),
      birdseye_(camera, with_guard_band(config.region, config.guard_m), config.hidden_below),
      model_(config.model != nullptr ? config.model : &builtin_marking_model()),
      cnn_(config.cnn != nullptr ? config.cnn : &builtin_marking_cnn()) {
  const int rows = birdseye_.rows(), cols = birdseye_.cols();
  const auto& region = config.region;
  window_cols_ = odd_at_least_3(config.local_window_m / region.y_step_m);
  window_rows_ = odd_at_least_3(config.local_window_m / region.x_step_m);
  word_gap_cols_ = static_cast<int>(std::lround(config.word_join_gap_m / region.y_step_m));
  word_max_cols_ = static_cast<int>(std::lround(config.word_max_width_m / region.y_step_m));
  min_part_area_px_ = std::max(
      1, static_cast<int>(std::lround(config.min_part_area_m2 / (region.x_step_m * region.y_step_m))));
  bev_.create(rows, cols, CV_8UC1);
  bev_.setTo(0);
  mask_.create(rows, cols, CV_8UC1);
  mask_.setTo(0);
  integral_.create(rows + 1, cols + 1, CV_32SC1);
  integral_.setTo(0);
  valid_integral_.create(rows + 1, cols + 1, CV_32SC1);
  valid_integral_.setTo(0);
  road_pixels_.create(rows, cols, CV_8UC2);
  road_integral_.create(rows + 1, cols + 1, CV_32SC2);
  road_integral_.setTo(cv::Scalar::all(0));
  at_edge_.create(rows, cols, CV_8UC1);
  unseen_kind_row_.assign(static_cast<std::size_t>(cols), 0);
  unseen_kind_across_.create(rows, cols, CV_8UC1);
  update_view_masks();
  // The road's horizon straight ahead: where a point 100 km ahead appears.
  Eigen::Vector2d far_ahead;
  horizon_known_ = camera_.ground_to_image({1.0e5, 0.0}, far_ahead) && std::isfinite(far_ahead.y());
  calibrated_horizon_row_ = horizon_known_ ? static_cast<float>(far_ahead.y()) : 0.0f;
  const std::size_t pixels = static_cast<std::size_t>(rows) * cols;
  pixel_labels_.assign(pixels, -1);
  run_above_.assign(pixels, 0);
  run_below_.assign(pixels, 0);
  // 8-connected labelling gives at most one provisional label per two pixels
  // of a row, plus one.
  const std::size_t max_labels = static_cast<std::size_t>(rows) * ((cols + 1) / 2 + 1);
  parent_.assign(max_labels, 0);
  label_box_.assign(max_labels, Part{});
  label_moments_.assign(max_labels, Moments{});
  fill_reached_.assign(pixels, 0);
  fill_queue_.assign(pixels, 0);
  parts_.assign(kMaxParts, Part{});
  group_parent_.assign(kMaxParts, 0);
  part_groupable_.assign(kMaxParts, 0);
  group_candidate_.assign(kMaxParts, -1);
}

void MarkingDetector::update_view_masks() {
  const int rows = birdseye_.rows(), cols = birdseye_.cols();
  const cv::Mat& valid = birdseye_.valid();
  // Valid-pixel counts change only with the view's row shift: integrated then.
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
  // see: paint there may go on beyond what is seen. Near only where every
  // unseen neighbour is level or below and unseen_below(). Run on every
  // move of the view (the horizon measured), so in passes over rows: each
  // pixel's kind of unseen, ORed across with its neighbours', then down.
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* v = valid.ptr<std::uint8_t>(r);
    std::uint8_t* kind = unseen_kind_row_.data();
    for (int c = 0; c < cols; ++c)
      kind[c] = v[c] != 0 ? 0 : birdseye_.unseen_below(r, c) ? kNearEdge : kOtherEdge;
    std::uint8_t* across = unseen_kind_across_.ptr<std::uint8_t>(r);
    across[0] = static_cast<std::uint8_t>(kind[0] | kind[std::min(cols - 1, 1)]);
    for (int c = 1; c < cols - 1; ++c)
      across[c] = static_cast<std::uint8_t>(kind[c - 1] | kind[c] | kind[c + 1]);
    across[cols - 1] = static_cast<std::uint8_t>(kind[std::max(0, cols - 2)] | kind[cols - 1]);
  }
  for (int r = 0; r < rows; ++r) {
    // The first and last rows stand in for the missing neighbour row: the
    // first is all border anyway, and ORing the last with itself adds nothing.
    const std::uint8_t* level = unseen_kind_across_.ptr<std::uint8_t>(r);
    const std::uint8_t* above = unseen_kind_across_.ptr<std::uint8_t>(std::max(0, r - 1));
    const std::uint8_t* below = unseen_kind_across_.ptr<std::uint8_t>(std::min(rows - 1, r + 1));
    const bool border_row = r == 0;
    const std::uint8_t near_row = r == rows - 1 ? kNearEdge : 0;
    std::uint8_t* out = at_edge_.ptr<std::uint8_t>(r);
    for (int c = 0; c < cols; ++c) {
      // An unseen pixel in the row above is never below this one.
      const std::uint8_t level_or_below = level[c] | below[c];
      const bool other = border_row || above[c] != 0 || (level_or_below & kOtherEdge) != 0;
      const bool near = ((level_or_below | near_row) & kNearEdge) != 0;
      out[c] = other ? kOtherEdge : near ? kNearEdge : 0;
    }
    out[0] = kOtherEdge;
    out[cols - 1] = kOtherEdge;
  }
}

bool MarkingDetector::usable(const cv::Mat& grey) const {
  return grey.type() == CV_8UC1 && grey.cols == camera_.width() && grey.rows == camera_.height() &&
         model_is_usable(*model_) && cnn_is_usable(*cnn_);
}

std::span<const Detection> MarkingDetector::detect(const cv::Mat& grey) {
  return detect_frame(grey, false);
}

std::span<const Detection> MarkingDetector::detect_frame(const cv::Mat& grey, bool still) {
  ++counters_.frames;
  if (!usable(grey)) return reject_frame();
  process(grey, still);
  // A view that is no road (a failing sensor, noise) has "lane lines" that
  // would drag the horizon the frames after it are seen with.
  const bool road_like = count_view() == ViewKind::Road;
  if (config_.horizon_from_lanes && horizon_known_) {
    if (const std::optional<float> measured = road_like ? measure_horizon_shift() : std::nullopt) {
      ++counters_.horizon_measured;
      horizon_estimate_ += config_.horizon_gain * (*measured - horizon_estimate_);
      // Moved by most of a row only: an estimate between two rows must not
      // switch the view back and forth every frame.
      if (std::abs(horizon_estimate_ - static_cast<float>(birdseye_.row_shift())) >= 0.75f)
        set_horizon_shift(static_cast<int>(std::lround(horizon_estimate_)));
    } else {
      ++counters_.horizon_unmeasured;
    }
  }
  return {detections_.data(), detection_count_};
}

std::span<const Detection> MarkingDetector::detect_still(const cv::Mat& grey) {
  if (!config_.horizon_from_lanes || !horizon_known_) return detect_frame(grey, true);
  ++counters_.frames;
  if (!usable(grey)) return reject_frame();
  horizon_estimate_ = 0.0f;
  set_horizon_shift(0);
  const DetectorCounters before = counters_;
  process(grey, true);
  std::optional<float> measured = measure_horizon_shift();
  const bool placed = measured.has_value();
  for (int look = 1; look < kStillLooks && measured; ++look) {
    const int rows = static_cast<int>(std::lround(*measured));
    if (rows == birdseye_.row_shift()) break;
    horizon_estimate_ = *measured;
    counters_ = before;
    set_horizon_shift(rows);
    process(grey, true);
    measured = measure_horizon_shift();
  }
  ++(placed ? counters_.horizon_measured : counters_.horizon_unmeasured);
  (void)count_view();
  return {detections_.data(), detection_count_};
}

ViewKind MarkingDetector::kind_of(ViewSpread spread) const {
  if (spread.blocks < config_.min_view_spread) return ViewKind::Flat;
  if (spread.blocks < config_.min_view_coherence * spread.pixels) return ViewKind::Noisy;
  return ViewKind::Road;
}

ViewKind MarkingDetector::count_view() {
  switch (last_view_) {
    case ViewKind::Flat:
      ++counters_.flat_frames;
      break;
    case ViewKind::Noisy:
      ++counters_.noisy_frames;
      break;
    case ViewKind::Cluttered:
      ++counters_.cluttered_frames;
      break;
    case ViewKind::Road:
    case ViewKind::Unusable:
      break;
  }
  return last_view_;
}

ViewSpread MarkingDetector::view_spread() const {
  // Over pixels and over blocks of the view: a sensor's noise, however
  // strong, averages out within a block; a road's lines, verges and light
  // do not. Every other row and column of each block is read.
  constexpr int kBlock = 16, kStep = 2;
  constexpr unsigned kMinSeen = (kBlock / kStep) * (kBlock / kStep) / 2;
  const cv::Mat& valid = birdseye_.valid();
  double blocks = 0.0, block_sum = 0.0, block_sum_sq = 0.0;
  std::uint64_t pixels = 0, pixel_sum = 0, pixel_sum_sq = 0;
  for (int r0 = 0; r0 + kBlock <= bev_.rows; r0 += kBlock) {
    for (int c0 = 0; c0 + kBlock <= bev_.cols; c0 += kBlock) {
      unsigned seen = 0, total = 0, total_sq = 0;
      for (int r = r0; r < r0 + kBlock; r += kStep) {
        const std::uint8_t* grey = bev_.ptr<std::uint8_t>(r);
        const std::uint8_t* in_view = valid.ptr<std::uint8_t>(r);
        for (int c = c0; c < c0 + kBlock; c += kStep) {
          if (in_view[c] == 0) continue;
          ++seen;
          total += grey[c];
          total_sq += unsigned{grey[c]} * grey[c];
        }
      }
      if (seen < kMinSeen) continue;  // mostly outside the image or under the bonnet
      pixels += seen;
      pixel_sum += total;
      pixel_sum_sq += total_sq;
      const double mean = static_cast<double>(total) / static_cast<double>(seen);
      blocks += 1.0;
      block_sum += mean;
      block_sum_sq += mean * mean;
    }
  }
  if (blocks < 2.0) return {};
  const auto deviation = [](double sum, double sum_sq, double n) {
    const double mean = sum / n;
    return static_cast<float>(std::sqrt(std::max(0.0, sum_sq / n - mean * mean)));
  };
  return {deviation(static_cast<double>(pixel_sum), static_cast<double>(pixel_sum_sq),
                    static_cast<double>(pixels)),
          deviation(block_sum, block_sum_sq, blocks)};
}

std::span<const Detection> MarkingDetector::reject_frame() {
  ++counters_.bad_frames;
  last_view_ = ViewKind::Unusable;
  last_view_spread_ = {};
  detection_count_ = 0;
  candidate_count_ = 0;
  lane_segment_count_ = 0;
  return {};
}

std::optional<float> MarkingDetector::measure_horizon_shift() const {
  const float reach = static_cast<float>(config_.horizon_max_shift_px);
  const float width = static_cast<float>(camera_.width());
  const VanishingSearch search{calibrated_horizon_row_ - reach, calibrated_horizon_row_ + reach,
                               -0.5f * width, 1.5f * width};
  const std::optional<float> row = vanishing_row(lane_segments(), search);
  if (!row) return std::nullopt;
  return *row - calibrated_horizon_row_;
}

void MarkingDetector::set_horizon_shift(int rows) {
  rows = std::clamp(rows, -config_.horizon_max_shift_px, config_.horizon_max_shift_px);
  if (rows == birdseye_.row_shift()) return;
  birdseye_.set_row_shift(rows, config_.hidden_below_follows_horizon ? rows : 0);
  update_view_masks();
  ++counters_.horizon_moves;
}

MarkingDetector::Axis MarkingDetector::axis(const Part& box, const Moments& sums) const {
  const auto& region = config_.region;
  const double n = box.area;
  const double mean_row = static_cast<double>(sums.row) / n;
  const double mean_col = static_cast<double>(sums.col) / n;
  // Second moments in metres, along the road (rows) and across it (columns).
  const double xs = region.x_step_m, ys = region.y_step_m;
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

bool MarkingDetector::encloses_road(int label, const Part& box) {
  // Road inside the outline is what the box's border cannot reach without
  // crossing this part's paint (4-connected, as the paint is 8-connected).
  constexpr float kMinEnclosedM2 = 0.1f;
  const int cols = mask_.cols;
  const auto& region = config_.region;
  const int min_enclosed =
      std::max(1, static_cast<int>(std::lround(kMinEnclosedM2 / (region.x_step_m * region.y_step_m))));
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
    std::fill_n(fill_reached_.begin() + static_cast<std::ptrdiff_t>(row) * cols + box.col0,
                box.col1 - box.col0 + 1, std::uint8_t{0});
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
  const int box_pixels = (box.row1 - box.row0 + 1) * (box.col1 - box.col0 + 1);
  const int enclosed = box_pixels - box.area - static_cast<int>(tail);
  return enclosed >= min_enclosed;
}

void MarkingDetector::note_lane_segment(const Axis& axis) {
  const auto& region = config_.region;
  const double xs = region.x_step_m, ys = region.y_step_m;
  const double length = axis.length_m, width = axis.width_m, angle = axis.angle_rad;
  const double mean_row = axis.mean_row, mean_col = axis.mean_col;
  // Long and thin: at least seven times as long as wide (blur and a pitch
  // other than calibrated widen lines in the view, so no fixed width);
  // dashes count.
  constexpr double kMinElongation = 7.0;
  if (length < kMinHorizonLineM || length < kMinElongation * width) return;
  // Its axis, from the road's direction: lines across the road (stop lines)
  // do not run to the horizon.
  constexpr double kMaxAngleRad = 0.3;
  if (std::abs(angle) > kMaxAngleRad) return;
  const double half_rows = 0.5 * length * std::cos(angle) / xs;
  const double half_cols = 0.5 * length * std::sin(angle) / ys;
  std::array<Eigen::Vector2d, 2> ends;
  for (int k = 0; k < 2; ++k) {
    const double sign = k == 0 ? -1.0 : 1.0;
    const float row = static_cast<float>(mean_row + sign * half_rows);
    const float col = static_cast<float>(mean_col + sign * half_cols);
    if (!camera_.ground_to_image({birdseye_.ground_x(row), birdseye_.ground_y(col)}, ends[k])) return;
  }
  const float shift = static_cast<float>(birdseye_.row_shift());
  const ImageSegment segment{static_cast<float>(ends[0].x()), static_cast<float>(ends[0].y()) + shift,
                             static_cast<float>(ends[1].x()), static_cast<float>(ends[1].y()) + shift};
  // Keep the longest: they say the most about where the lines meet.
  std::size_t slot = lane_segment_count_;
  if (slot == lane_segments_.size()) {
    slot = static_cast<std::size_t>(std::min_element(lane_lengths_.begin(), lane_lengths_.end()) -
                                    lane_lengths_.begin());
    if (!(static_cast<float>(length) > lane_lengths_[slot])) return;
  } else {
    ++lane_segment_count_;
  }
  lane_segments_[slot] = segment;
  lane_lengths_[slot] = static_cast<float>(length);
}

void MarkingDetector::process(const cv::Mat& grey, bool still) {
  detection_count_ = 0;
  candidate_count_ = 0;
  birdseye_.warp(grey, bev_);
  last_view_spread_ = view_spread();
  last_view_ = kind_of(last_view_spread_);
  if (last_view_ != ViewKind::Road) {
    // No road to look for paint on: whatever "paint" noise or a flat grey
    // showed would be no marking, and costs the most time of all frames.
    for (int r = 0; r < mask_.rows; ++r) std::fill_n(mask_.ptr<std::uint8_t>(r), mask_.cols, std::uint8_t{0});
    lane_segment_count_ = 0;
    return;
  }
  // Parts or candidates dropped at the caps in this frame make it cluttered.
  const std::uint64_t dropped_before = counters_.parts_dropped + counters_.candidates_dropped;
  threshold();
  cut_line_junctions();
  const std::size_t part_count = label_parts();
  group_parts(part_count);
  if (counters_.parts_dropped + counters_.candidates_dropped > dropped_before)
    last_view_ = ViewKind::Cluttered;
  for (std::size_t i = 0; i < candidate_count_; ++i) classify(candidates_[i]);
  const std::size_t joined = join_across_strokes(candidates(), {reported_by_.data(), candidate_count_}) +
                             join_split_words(candidates(), {reported_by_.data(), candidate_count_},
                                              word_gap_cols_, word_max_cols_, config_.stroke_min_shared);
  counters_.joined += joined;
  for (std::size_t i = 0; i < candidate_count_; ++i) {
    if (reported_by_[i] != static_cast<std::int32_t>(i)) {                 // in a word's detection
      if (candidates_[i].predicted == kRejectClass) ++counters_.rejected;  // a broken letter
      continue;
    }
    // The first of a word's candidates split by its I reports the word.
    const bool first_of_word = joined > 0 && reports_others({reported_by_.data(), candidate_count_}, i);
    Candidate word;  // filled only for a word: a copy, as rare as they are
    if (first_of_word) word = joined_candidate(candidates(), {reported_by_.data(), candidate_count_}, i);
    const Candidate& candidate = first_of_word ? word : candidates_[i];
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
    const bool partial = candidate.clipped_near_only && still && config_.report_partial_in_stills;
    if (candidate.clipped && !config_.report_clipped && !partial) {
      ++counters_.clipped;
      continue;
    }
    if (beyond_region(candidate)) {
      ++counters_.beyond_region;
      continue;
    }
    if (candidate.score < config_.min_score) {
      ++counters_.low_score;
      continue;
    }
    if (last_view_ == ViewKind::Cluttered) {
      // Examined in part only, up to the caps: what it found is no more
      // trustworthy than what it left out.
      ++counters_.detections_withheld;
      continue;
    }
    if (detection_count_ == kMaxDetections) {
      ++counters_.detections_dropped;
      continue;
    }
    Detection& d = detections_[detection_count_++];
    d.label = static_cast<Label>(candidate.predicted);
    d.score = candidate.score;
    d.partial = partial;
    locate(candidate, d);
    ++counters_.detections;
    if (partial) ++counters_.partial;
  }
}

void MarkingDetector::threshold() {
  const int rows = bev_.rows, cols = bev_.cols;
  cv::integral(bev_, integral_, CV_32S);  // into the buffer sized at start-up
  const int half_r = window_rows_ / 2, half_c = window_cols_ / 2;
  // Paint: value > mean + max(contrast, ratio * mean).
  const std::int32_t ratio_q8 = static_cast<std::int32_t>(std::lround(config_.min_contrast_ratio * 256.0f));
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
      // Bitwise, not short-circuit: no branch, so the loop vectorises.
      const int paint = static_cast<int>(v[c] != 0) &
                        static_cast<int>(brighter_than_mean(in[c], sum, count, contrast_q8, ratio_q8));
      out[c] = static_cast<std::uint8_t>(paint * 255);
    };
    // Where the window lies wholly inside the row its bounds are fixed
    // offsets, and the loop vectorises; the borders clamp them.
    const int inner_begin = std::min(cols, half_c), inner_end = std::max(inner_begin, cols - half_c);
    for (int c = 0; c < inner_begin; ++c) decide(c, 0, std::min(cols, c + half_c + 1));
    for (int c = inner_begin; c < inner_end; ++c) decide(c, c - half_c, c + half_c + 1);
    for (int c = inner_end; c < cols; ++c) decide(c, std::max(0, c - half_c), cols);
  }
  if (config_.quadrant_min_contrast > 0) veto_one_sided_paint();
}

void MarkingDetector::veto_one_sided_paint() {
  const int rows = bev_.rows, cols = bev_.cols;
  // Integral of the road, i.e. of the pixels less the paint found so far (its
  // values and its count), so that a quadrant that an arrow's head fills is
  // judged by the road around the head, not by the head. threshold() paints
  // valid pixels only: the road is what is valid and not painted.
  const cv::Mat& valid = birdseye_.valid();
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* in = bev_.ptr<std::uint8_t>(r);
    const std::uint8_t* m = mask_.ptr<std::uint8_t>(r);
    const std::uint8_t* v = valid.ptr<std::uint8_t>(r);
    std::uint8_t* road = road_pixels_.ptr<std::uint8_t>(r);
    for (int c = 0; c < cols; ++c) {
      const std::uint8_t is_road = static_cast<std::uint8_t>((v[c] != 0) & (m[c] == 0));
      road[2 * c] = static_cast<std::uint8_t>(in[c] * is_road);
      road[2 * c + 1] = is_road;
    }
  }
  cv::integral(road_pixels_, road_integral_, CV_32S);
  const int half_r = window_rows_ / 2, half_c = window_cols_ / 2;
  const std::int32_t ratio_q8 =
      static_cast<std::int32_t>(std::lround(config_.quadrant_min_contrast_ratio * 256.0f));
  const std::int32_t contrast_q8 = config_.quadrant_min_contrast * 256;
  // A quadrant with little road (the view's edge, paint) says too little
  // about the road there to veto anything.
  const std::int32_t min_count = std::max(1, (half_r + 1) * (half_c + 1) / 4);
  for (int r = 0; r < rows; ++r) {
    std::uint8_t* out = mask_.ptr<std::uint8_t>(r);
    const std::uint8_t* in = bev_.ptr<std::uint8_t>(r);
    // The quadrants' rows: [r - half_r, r] and [r, r + half_r], clamped.
    const cv::Vec2i* row_bounds[2][2] = {
        {road_integral_.ptr<cv::Vec2i>(std::max(0, r - half_r)), road_integral_.ptr<cv::Vec2i>(r + 1)},
        {road_integral_.ptr<cv::Vec2i>(r), road_integral_.ptr<cv::Vec2i>(std::min(rows, r + half_r + 1))}};
    for (int c = next_painted(out, 0, cols); c < cols; c = next_painted(out, c + 1, cols)) {
      const int col_bounds[2][2] = {{std::max(0, c - half_c), c + 1}, {c, std::min(cols, c + half_c + 1)}};
      for (const auto& rb : row_bounds) {
        for (const auto& cb : col_bounds) {
          const cv::Vec2i road = rb[1][cb[1]] - rb[1][cb[0]] - rb[0][cb[1]] + rb[0][cb[0]];
          if (road[1] < min_count) continue;
          if (!brighter_than_mean(in[c], road[0], road[1], contrast_q8, ratio_q8)) out[c] = 0;
        }
      }
    }
  }
}

void MarkingDetector::cut_line_junctions() {
  const int rows = mask_.rows, cols = mask_.cols;
  const int along =
      std::max(2, static_cast<int>(std::lround(config_.junction_along_m / config_.region.x_step_m)));
  const int across =
      std::max(2, static_cast<int>(std::lround(config_.junction_across_m / config_.region.y_step_m)));
  // Vertical run lengths, saturating (int16): from above, then from below.
  // `previous` is the run one row back (none for the first row); written
  // without branches so that the loop vectorises.
  const auto extend_runs = [cols](const std::uint8_t* m, const std::int16_t* previous, std::int16_t* here) {
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
  const int long_bar =
      std::max(across, static_cast<int>(std::lround(config_.junction_long_bar_m / config_.region.y_step_m)));
  // A worn bar beside the run [c, end) of row `m`: the length (long_bar,
  // across or 0) of a stretch at least min_fill paint starting within
  // `bridge` of it. Asked only of runs on a line (few per row), and most
  // of those have road beside them.
  const bool worn_bars = config_.junction_min_fill > 0.0f;
  const float min_fill = config_.junction_min_fill;
  const int bridge = static_cast<int>(std::lround(config_.junction_bridge_m / config_.region.y_step_m));
  const int worn_along =
      static_cast<int>(std::lround(config_.junction_worn_along_m / config_.region.x_step_m));
  const auto worn_bar_beside = [&](int c, int end, const std::uint8_t* m) {
    const auto filled = [&](int from, int to) {  // [from, to) inside the row
      int paint = 0;
      for (int k = from; k < to; ++k) paint += m[k] != 0;
      return static_cast<float>(paint) >= min_fill * static_cast<float>(to - from);
    };
    int right = end;  // the first paint after the run, within the bridge
    while (right < cols && right - end < bridge && m[right] == 0) ++right;
    int left = c - 1;  // the last paint before it
    while (left >= 0 && c - 1 - left < bridge && m[left] == 0) --left;
    const bool paint_right = right < cols && m[right] != 0;
    const bool paint_left = left >= 0 && m[left] != 0;
    for (const int length : {long_bar, across}) {
      if (paint_right && right + length <= cols && filled(right, right + length)) return length;
      if (paint_left && left + 1 - length >= 0 && filled(left + 1 - length, left + 1)) return length;
    }
    return 0;
  };
  bool any = false;
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* m = mask_.ptr<std::uint8_t>(r);
    const std::int16_t* above = run_above_.data() + static_cast<std::size_t>(r) * cols;
    std::int16_t* below = run_below_.data() + static_cast<std::size_t>(r) * cols;
    int c = 0;
    while ((c = next_painted(m, c, cols)) < cols) {
      int end = c;
      while (end < cols && m[end] != 0) ++end;
      const bool unbroken = end - c >= across;
      int beside = 0;
      if (!unbroken && worn_bars) {
        bool on_line = false;
        for (int k = c; k < end && !on_line; ++k) on_line = above[k] + below[k] - 1 >= worn_along;
        if (on_line) beside = worn_bar_beside(c, end, m);
      }
      if (unbroken || beside > 0) {
        const std::int16_t mark = std::max(end - c, beside) >= long_bar ? -2 : -1;
        const int line_length = unbroken ? along : worn_along;
        for (int k = c; k < end; ++k)
          if (above[k] + below[k] - 1 >= line_length) {
            below[k] = mark;
            any = true;
          }
      }
      c = end;
    }
  }
  if (!any) return;
  const int margin =
      std::max(1, static_cast<int>(std::lround(config_.junction_cut_margin_m / config_.region.x_step_m)));
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
  lane_segment_count_ = 0;
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* m = mask_.ptr<std::uint8_t>(r);
    std::int32_t* row = labels + static_cast<std::size_t>(r) * cols;
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
  }
  // Merge each provisional label's box into its root's.
  for (int label = 0; label < next; ++label) {
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
  const auto& region = config_.region;
  std::size_t count = 0;
  stroke_count_ = 0;
  for (int label = 0; label < next; ++label) {
    if (parent[label] != label) continue;
    const Part& box = label_box_[label];
    if (box.area < min_part_area_px_) continue;
    const Axis part_axis = axis(box, label_moments_[label]);
    if (config_.horizon_from_lanes) note_lane_segment(part_axis);
    const float length = static_cast<float>(box.row1 - box.row0 + 1) * region.x_step_m;
    const float width = static_cast<float>(box.col1 - box.col0 + 1) * region.y_step_m;
    const float fill = static_cast<float>(box.area) /
                       static_cast<float>((box.row1 - box.row0 + 1) * (box.col1 - box.col0 + 1));
    // Lines at an angle to the view's columns (a bend, a road crossed
    // obliquely) are thin along their own axis, not their box's.
    const bool oblique_line =
        part_axis.width_m <= config_.line_max_width_m && part_axis.length_m >= config_.line_min_length_m;
    // A sparse part is a line or kerb unless it is a closed outline.
    const bool sparse = width >= config_.sparse_min_size_m && length >= config_.sparse_min_size_m &&
                        fill < config_.sparse_max_fill;
    const bool straight_line = width <= config_.line_max_width_m && length >= config_.line_min_length_m;
    if (straight_line || oblique_line || (sparse && !encloses_road(label, box))) {
      ++counters_.lane_lines;
      if ((straight_line || oblique_line) && length <= config_.group_max_part_m) {
        if (stroke_count_ < kMaxStrokes)
          strokes_[stroke_count_++] = box;
        else
          ++counters_.strokes_dropped;
      }
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
    parts_[count] = box;
    parts_[count++].thin = part_axis.width_m <= config_.line_max_width_m;
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
  const int line_cols = static_cast<int>(std::lround(config_.line_max_width_m / region.y_step_m));
  const int stripe_gap_cols = static_cast<int>(std::lround(config_.stripe_gap_across_m / region.y_step_m));
  const int stripe_min_rows = static_cast<int>(std::lround(config_.stripe_min_length_m / region.x_step_m));
  const int stripe_max_cols = static_cast<int>(std::lround(config_.stripe_max_width_m / region.y_step_m));
  constexpr std::uint8_t kGroupable = 1, kStripe = 2;
  const auto grouping = [&](const Part& p) -> std::uint8_t {
    const bool bar = p.col1 - p.col0 + 1 >= bar_min_cols && p.row1 - p.row0 + 1 <= bar_max_rows;
    // A thin part running out of the view (a lane dash coming into sight,
    // too short yet to be set apart as a line; on a bend at an angle) would
    // make a marking it joins look cut by the edge.
    const bool line_coming_in =
        (p.col1 - p.col0 + 1 <= line_cols || p.thin) && (touched_edges(p) & kOtherEdge) != 0;
    if (p.col1 - p.col0 >= max_cols || p.row1 - p.row0 >= max_rows || bar || line_coming_in) return 0;
    // (A piece of a lane dash is as thin as a line, a stripe wider.)
    const int rows = p.row1 - p.row0 + 1, cols = p.col1 - p.col0 + 1;
    const float fill = static_cast<float>(p.area) / static_cast<float>(rows * cols);
    const bool stripe = rows >= stripe_min_rows && cols > line_cols && cols <= stripe_max_cols &&
                        fill >= config_.stripe_min_fill;
    return stripe ? kGroupable | kStripe : kGroupable;
  };
  // Two stripes side by side: most of the shorter one's rows shared.
  const auto stripes_side_by_side = [&](const Part& a, const Part& b) {
    if (b.col0 > a.col1 + stripe_gap_cols || a.col0 > b.col1 + stripe_gap_cols) return false;
    const int shared = rows_shared(a, b);
    const int shorter = std::min(rows_of(a), rows_of(b));
    return static_cast<float>(shared) >= config_.stripe_min_shared * static_cast<float>(shorter);
  };
  std::int32_t* parent = group_parent_.data();
  // Decided once per part: the pairs below would scan a thin part's edge
  // paint once per partner.
  for (std::size_t i = 0; i < part_count; ++i) {
    parent[i] = static_cast<std::int32_t>(i);
    part_groupable_[i] = grouping(parts_[i]);
  }
  for (std::size_t i = 0; i < part_count; ++i) {
    const Part& a = parts_[i];
    if (part_groupable_[i] == 0) continue;
    for (std::size_t j = i + 1; j < part_count; ++j) {
      const Part& b = parts_[j];
      if (part_groupable_[j] == 0) continue;
      const bool close = b.col0 <= a.col1 + gap_cols && a.col0 <= b.col1 + gap_cols &&
                         b.row0 <= a.row1 + gap_rows && a.row0 <= b.row1 + gap_rows;
      const bool stripes =
          (part_groupable_[i] & part_groupable_[j] & kStripe) != 0 && stripes_side_by_side(a, b);
      if (close || stripes) unite(parent, static_cast<int>(i), static_cast<int>(j));
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
      c.across_stroke = -1;
      continue;
    }
    Candidate& c = candidates_[slot];
    grow_box(c, p);
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
    const std::uint8_t edges = touched_edges(c);
    c.clipped = edges != 0;
    c.clipped_near_only = edges == kNearEdge;
    candidates_[kept++] = c;
  }
  candidate_count_ = kept;
  counters_.candidates += kept;
  link_across_strokes(gap_cols);
}

void MarkingDetector::link_across_strokes(int gap_cols) {
  for (std::size_t s = 0; s < stroke_count_; ++s) {
    const Part& stroke = strokes_[s];
    // A letter's group beside the stroke: close across, along the stroke's
    // whole length, and at most twice as long (its group may have taken in
    // paint just beyond the letters).
    const auto beside = [&](const Candidate& c) {
      const int shared = rows_shared(c, stroke);
      return static_cast<float>(shared) >= config_.stroke_min_shared * static_cast<float>(rows_of(stroke)) &&
             2 * shared >= rows_of(c);
    };
    int left = -1, right = -1;
    for (std::size_t i = 0; i < candidate_count_; ++i) {
      const Candidate& c = candidates_[i];
      if (!beside(c)) continue;
      // (A box may reach a column or two into the stroke's: letters slanted
      // in the view on a bend.)
      if (c.col0 < stroke.col0 && c.col1 <= stroke.col1 && stroke.col0 - c.col1 - 1 <= gap_cols)
        left = static_cast<int>(i);
      if (c.col1 > stroke.col1 && c.col0 >= stroke.col0 && c.col0 - stroke.col1 - 1 <= gap_cols)
        right = static_cast<int>(i);
    }
    if (left >= 0 && right >= 0) {
      candidates_[static_cast<std::size_t>(left)].across_stroke = right;
    } else if (left >= 0 || right >= 0) {
      // Letters on one side only: those on the other may have run out of
      // the view, the stroke with them or as a sliver beside it (the X of
      // XING cut to its upright by the image's side).
      const int side = left >= 0 ? 1 : -1;  // towards the missing letters
      if (runs_out_of_view(stroke, side, gap_cols)) {
        Candidate& letters = candidates_[static_cast<std::size_t>(left >= 0 ? left : right)];
        letters.clipped = true;
        letters.clipped_near_only = false;
      }
    }
  }
  // A word is seen whole only where all its letters are: the letters across
  // a stroke from a cut one (the X of XING run out of the image's side) are
  // cut too, else their half would be reported as the word, a metre off.
  // Cuts only spread, so this settles within one pass per link.
  bool spread = true;
  for (std::size_t pass = 0; spread && pass < candidate_count_; ++pass) {
    spread = false;
    for (std::size_t i = 0; i < candidate_count_; ++i) {
      const int j = candidates_[i].across_stroke;
      if (j < 0) continue;
      Candidate& a = candidates_[i];
      Candidate& b = candidates_[static_cast<std::size_t>(j)];
      const bool clipped = a.clipped || b.clipped;
      const bool near_only =
          clipped && (!a.clipped || a.clipped_near_only) && (!b.clipped || b.clipped_near_only);
      for (Candidate* c : {&a, &b}) {
        if (c->clipped == clipped && c->clipped_near_only == near_only) continue;
        c->clipped = clipped;
        c->clipped_near_only = near_only;
        spread = true;
      }
    }
  }
}

bool MarkingDetector::runs_out_of_view(const Part& stroke, int side, int gap_cols) const {
  if ((touched_edges(stroke) & kOtherEdge) != 0) return true;
  const int rows = rows_of(stroke);
  for (std::size_t t = 0; t < stroke_count_; ++t) {
    const Part& beyond = strokes_[t];
    const int gap = side > 0 ? beyond.col0 - stroke.col1 - 1 : stroke.col0 - beyond.col1 - 1;
    const int shared = rows_shared(beyond, stroke);
    if (gap < 0 || gap > gap_cols ||
        static_cast<float>(shared) < config_.stroke_min_shared * static_cast<float>(rows))
      continue;
    if ((touched_edges(beyond) & kOtherEdge) != 0) return true;
  }
  return false;
}

std::size_t join_across_strokes(std::span<const Candidate> candidates, std::span<std::int32_t> reported_by) {
  const std::size_t n = std::min({candidates.size(), reported_by.size(), kMaxCandidates});
  const auto valid = [&](int i) { return i >= 0 && static_cast<std::size_t>(i) < n; };
  // The next candidate of i's class across the strokes to the right of
  // `i`, passing over at most kMaxBrokenLetters of other classes (a letter
  // broken by a shadow, its pieces taken for no marking; the diagonal of an
  // N between its upright and the I, taken for something else); -1 none.
  constexpr int kMaxBrokenLetters = 2;
  const auto next_marking = [&](std::size_t i) {
    int next = candidates[i].across_stroke;
    for (int hops = 0;
         valid(next) && candidates[static_cast<std::size_t>(next)].predicted != candidates[i].predicted;
         ++hops)
      next = hops < kMaxBrokenLetters ? candidates[static_cast<std::size_t>(next)].across_stroke : -1;
    return valid(next) ? next : -1;
  };
  const auto links_alike = [&](std::size_t i, int next) {
    return next >= 0 && candidates[i].predicted != kRejectClass &&
           candidates[static_cast<std::size_t>(next)].predicted == candidates[i].predicted;
  };
  for (std::size_t i = 0; i < n; ++i) reported_by[i] = static_cast<std::int32_t>(i);
  // A word starts where no candidate classified alike links to it.
  std::array<bool, kMaxCandidates> linked_to{};
  for (std::size_t i = 0; i < n; ++i)
    if (const int next = next_marking(i); links_alike(i, next))
      linked_to[static_cast<std::size_t>(next)] = true;
  std::size_t joined = 0;
  for (std::size_t first = 0; first < n; ++first) {
    if (linked_to[first]) continue;
    for (std::size_t at = first;;) {
      const int next = next_marking(at);
      if (!links_alike(first, next) || reported_by[static_cast<std::size_t>(next)] != next) break;
      // The broken letters on the way belong to the word too.
      for (int piece = candidates[at].across_stroke; piece != next;
           piece = candidates[static_cast<std::size_t>(piece)].across_stroke)
        if (reported_by[static_cast<std::size_t>(piece)] == piece)
          reported_by[static_cast<std::size_t>(piece)] = static_cast<std::int32_t>(first);
      reported_by[static_cast<std::size_t>(next)] = static_cast<std::int32_t>(first);
      ++joined;
      at = static_cast<std::size_t>(next);
    }
  }
  return joined;
}

bool is_word_class(int label) {
  static constexpr auto kWords = [] {
    std::array<bool, kMarkingClassCount> words{};
    for (const std::string_view name : {"stop", "ped", "xing", "bike", "25", "35", "40"})
      words[*marking_class_from_name(name)] = true;
    return words;
  }();
  return label >= 0 && label < static_cast<int>(kMarkingClassCount) &&
         kWords[static_cast<std::size_t>(label)];
}

std::size_t join_split_words(std::span<const Candidate> candidates, std::span<std::int32_t> reported_by,
                             int gap_cols, int max_cols, float min_shared) {
  const std::size_t n = std::min({candidates.size(), reported_by.size(), kMaxCandidates});
  // Alone: neither reports another nor is reported by one.
  std::array<bool, kMaxCandidates> alone{};
  for (std::size_t i = 0; i < n; ++i) alone[i] = reported_by[i] == static_cast<std::int32_t>(i);
  for (std::size_t i = 0; i < n; ++i)
    if (reported_by[i] != static_cast<std::int32_t>(i))
      alone[static_cast<std::size_t>(reported_by[i])] = false;
  // Letters of one word: close across, along most of the shorter one's
  // rows, and at most half as long again. (Whole ones only: a lane dash
  // coming into view beside a word is no letter of it, whatever it is
  // taken for.)
  const auto beside = [&](const Candidate& a, const Candidate& b) {
    const int gap = std::max(b.col0 - a.col1, a.col0 - b.col1) - 1;
    const int shared = rows_shared(a, b);
    const int shorter = std::min(rows_of(a), rows_of(b));
    const int longer = std::max(rows_of(a), rows_of(b));
    return gap >= 0 && gap <= gap_cols && 2 * longer <= 3 * shorter &&
           static_cast<float>(shared) >= min_shared * static_cast<float>(shorter);
  };
  const auto letter_of = [&](std::size_t i, int label) {
    return alone[i] && candidates[i].predicted == label && !candidates[i].clipped;
  };
  std::size_t joined = 0;
  std::array<std::size_t, kMaxCandidates> word{};  // the word's candidates, first first
  for (std::size_t first = 0; first < n; ++first) {
    const int label = candidates[first].predicted;
    if (!is_word_class(label) || !letter_of(first, label)) continue;
    std::size_t letters = 1;
    word[0] = first;
    int col0 = candidates[first].col0, col1 = candidates[first].col1;
    // The word grows by the letters beside any of its own, while narrow
    // enough to be one word.
    for (bool grew = true; grew;) {
      grew = false;
      for (std::size_t j = 0; j < n; ++j) {
        const Candidate& letter = candidates[j];
        if (j == first || !letter_of(j, label)) continue;
        if (std::max(col1, letter.col1) - std::min(col0, letter.col0) + 1 > max_cols) continue;
        const auto next_to = [&](std::size_t member) { return beside(candidates[member], letter); };
        if (std::none_of(word.begin(), word.begin() + static_cast<std::ptrdiff_t>(letters), next_to))
          continue;
        reported_by[j] = static_cast<std::int32_t>(first);
        alone[j] = false;
        word[letters++] = j;
        col0 = std::min(col0, letter.col0);
        col1 = std::max(col1, letter.col1);
        ++joined;
        grew = true;
      }
    }
    if (letters > 1) alone[first] = false;
  }
  return joined;
}

bool reports_others(std::span<const std::int32_t> reported_by, std::size_t first) {
  for (std::size_t j = 0; j < reported_by.size(); ++j)
    if (j != first && reported_by[j] == static_cast<std::int32_t>(first)) return true;
  return false;
}

Candidate joined_candidate(std::span<const Candidate> candidates, std::span<const std::int32_t> reported_by,
                           std::size_t first) {
  Candidate c = candidates[first];
  const float metres_per_row = c.length_m / static_cast<float>(c.row1 - c.row0 + 1);
  const float metres_per_col = c.width_m / static_cast<float>(c.col1 - c.col0 + 1);
  bool cut_elsewhere = c.clipped && !c.clipped_near_only;
  for (std::size_t j = 0; j < candidates.size() && j < reported_by.size(); ++j) {
    if (j == first || reported_by[j] != static_cast<std::int32_t>(first)) continue;
    const Candidate& other = candidates[j];
    grow_box(c, other);
    c.parts += other.parts;
    if (other.predicted == c.predicted) c.score = std::max(c.score, other.score);
    c.clipped = c.clipped || other.clipped;
    cut_elsewhere = cut_elsewhere || (other.clipped && !other.clipped_near_only);
  }
  c.length_m = metres_per_row * static_cast<float>(c.row1 - c.row0 + 1);
  c.width_m = metres_per_col * static_cast<float>(c.col1 - c.col0 + 1);
  c.clipped_near_only = c.clipped && !cut_elsewhere;
  return c;
}

bool is_piece_of_larger(std::span<const Candidate> candidates, std::size_t index) {
  const Candidate& c = candidates[index];
  for (std::size_t j = 0; j < candidates.size(); ++j) {
    const Candidate& outer = candidates[j];
    if (j == index || (outer.predicted != c.predicted && !outer.clipped)) continue;
    const int shared_cols = std::min(c.col1, outer.col1) - std::max(c.col0, outer.col0) + 1;
    const int shared_rows = rows_shared(c, outer);
    if (shared_cols <= 0 || shared_rows <= 0) continue;
    const int area = (c.col1 - c.col0 + 1) * (c.row1 - c.row0 + 1);
    const bool mostly_inside =
        static_cast<float>(shared_cols * shared_rows) >= kPieceMinInside * static_cast<float>(area);
    const bool larger = (outer.col1 - outer.col0 + 1) * (outer.row1 - outer.row0 + 1) > area;
    if (mostly_inside && larger) return true;
  }
  return false;
}

template <typename Box>
std::uint8_t MarkingDetector::touched_edges(const Box& c) const {
  // Paint of the box next to the edge of the view: the marking may go on
  // beyond it. The box alone would say so for every marking whose box
  // corner reaches into the unseen corners of the view.
  std::uint8_t touched = 0;
  for (int row = c.row0; row <= c.row1; ++row) {
    const std::uint8_t* paint = mask_.ptr<std::uint8_t>(row);
    const std::uint8_t* edge = at_edge_.ptr<std::uint8_t>(row);
    for (int col = c.col0; col <= c.col1; ++col) touched |= paint[col] & edge[col];
    if (touched == (kNearEdge | kOtherEdge)) break;
  }
  return touched;
}

void MarkingDetector::classify(Candidate& candidate) {
  const PatchBox box{candidate.col0,     candidate.row0,    candidate.col1, candidate.row1,
                     candidate.length_m, candidate.width_m, candidate.parts};
  compute_features(bev_, mask_, box, scratch_, candidate.features);
  std::array<float, kClassifierOutputs> probabilities;
  candidate.predicted = perception::classify(*model_, cnn_, config_.cnn_share, config_.skip_networks_at,
                                             candidate.features, scratch_, cnn_scratch_, probabilities);
  candidate.score = probabilities[candidate.predicted];
}

MarkingDetector::GroundBox MarkingDetector::ground_box(const Candidate& candidate) const {
  return {birdseye_.ground_x(static_cast<float>(candidate.row0) - 0.5f),
          birdseye_.ground_x(static_cast<float>(candidate.row1) + 0.5f),
          birdseye_.ground_y(static_cast<float>(candidate.col0) - 0.5f),
          birdseye_.ground_y(static_cast<float>(candidate.col1) + 0.5f)};
}

void MarkingDetector::locate(const Candidate& candidate, Detection& out) const {
  const auto [far, near, left, right] = ground_box(candidate);
  // The dataset's corner order: near left, near right, far right, far left.
  const std::array<std::array<float, 2>, 4> corners = {
      {{near, left}, {near, right}, {far, right}, {far, left}}};
  for (std::size_t i = 0; i < 4; ++i) {
    Eigen::Vector2d pixel(-1.0, -1.0);
    camera_.ground_to_image({corners[i][0], corners[i][1]}, pixel);
    out.quad[i] = {static_cast<float>(pixel.x()),
                   static_cast<float>(pixel.y()) + static_cast<float>(birdseye_.row_shift())};
  }
  out.ground_x = 0.5f * (near + far);
  out.ground_y = 0.5f * (left + right);
}

bool MarkingDetector::beyond_region(const Candidate& candidate) const {
  // The centre as locate() gives it.
  const auto [far, near, left, right] = ground_box(candidate);
  const float x = 0.5f * (near + far), y = 0.5f * (left + right);
  const auto& region = config_.region;
  return x > region.x_far_m || y > region.y_left_m || y < region.y_right_m;
}

bool load_detector_config(const std::string& path, DetectorConfig& config, std::string& error) {
  try {
    std::optional<cv::FileStorage> storage = open_storage_file(path, error);
    if (!storage) return false;
    cv::FileStorage& fs = *storage;
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
        {"detector_guard_m", &c.guard_m, 0.0f, 5.0f},
        {"detector_local_window_m", &c.local_window_m, 0.1f, 20.0f},
        {"detector_min_score", &c.min_score, 0.0f, 1.0f},
        {"detector_horizon_gain", &c.horizon_gain, 0.001f, 1.0f},
        {"detector_cnn_share", &c.cnn_share, 0.0f, 1.0f},
        {"detector_skip_networks_at", &c.skip_networks_at, 0.0f, 2.0f},
        {"detector_min_view_spread", &c.min_view_spread, 0.0f, 64.0f},
        {"detector_min_view_coherence", &c.min_view_coherence, 0.0f, 1.0f},
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
    const auto read_switch = [&](const char* name, bool& value) {
      const cv::FileNode node = fs[name];
      if (node.empty()) return true;
      if (!node.isInt() || (static_cast<int>(node) != 0 && static_cast<int>(node) != 1)) {
        error = path + ": " + name + " must be 0 or 1";
        return false;
      }
      value = static_cast<int>(node) == 1;
      return true;
    };
    if (!read_switch("detector_horizon_from_lanes", c.horizon_from_lanes) ||
        !read_switch("detector_hidden_below_follows_horizon", c.hidden_below_follows_horizon))
      return false;
    const cv::FileNode max_shift = fs["detector_horizon_max_shift_px"];
    if (!max_shift.empty()) {
      if (!max_shift.isInt() || static_cast<int>(max_shift) < 0 || static_cast<int>(max_shift) > 200) {
        error = path + ": detector_horizon_max_shift_px must be a whole number 0..200";
        return false;
      }
      c.horizon_max_shift_px = static_cast<int>(max_shift);
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
      error = path + ": detector region has " + std::to_string(cells) + " bird's-eye pixels; at most 4e6";
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
