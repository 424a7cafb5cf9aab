#include "app/perception/marking_detector.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace markloop::perception {
namespace {

// detect_still() warps an image again with the horizon where the last look
// put it, up to this many looks in all: the farther the view is from the
// true horizon, the more it bends the lines that measure it.
constexpr int kStillLooks = 3;

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
      bev_(birdseye_.rows(), birdseye_.cols(), CV_8UC1, cv::Scalar(0)),
      edges_(birdseye_),
      lanes_(camera_, birdseye_, config.region, config.horizon_max_shift_px),
      paint_(config, config.region, birdseye_.rows(), birdseye_.cols()),
      labeller_(config, config.group_max_part_m, config.region, birdseye_.rows(), birdseye_.cols()),
      grouper_(config, config, config.region, paint_, edges_),
      classifier_(config),
      words_(config, config.stroke_min_shared, config.region),
      crosswalks_(config, config.bar_max_length_m, config.region, edges_),
      locator_(camera_, birdseye_, config.region) {}

bool MarkingDetector::usable(const cv::Mat& grey) const {
  return grey.type() == CV_8UC1 && grey.cols == camera_.width() && grey.rows == camera_.height() &&
         classifier_.usable();
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
  if (config_.horizon_from_lanes && lanes_.known()) {
    if (road_like)
      follow_horizon();
    else
      ++counters_.horizon_unmeasured;
  }
  return {detections_.data(), detection_count_};
}

void MarkingDetector::follow_horizon() {
  const std::optional<float> measured = lanes_.measure_shift();
  if (!measured) {
    ++counters_.horizon_unmeasured;
    return;
  }
  ++counters_.horizon_measured;
  horizon_estimate_ += config_.horizon_gain * (*measured - horizon_estimate_);
  // Moved by most of a row only: an estimate between two rows must not
  // switch the view back and forth every frame.
  if (std::abs(horizon_estimate_ - static_cast<float>(birdseye_.row_shift())) >= 0.75f)
    set_horizon_shift(static_cast<int>(std::lround(horizon_estimate_)));
}

std::span<const Detection> MarkingDetector::detect_still(const cv::Mat& grey) {
  if (!config_.horizon_from_lanes || !lanes_.known()) return detect_frame(grey, true);
  ++counters_.frames;
  if (!usable(grey)) return reject_frame();
  horizon_estimate_ = 0.0f;
  set_horizon_shift(0);
  const DetectorCounters before = counters_;
  process(grey, true);
  std::optional<float> measured = lanes_.measure_shift();
  const bool placed = measured.has_value();
  for (int look = 1; look < kStillLooks && measured; ++look) {
    const int rows = static_cast<int>(std::lround(*measured));
    if (rows == birdseye_.row_shift()) break;
    horizon_estimate_ = *measured;
    counters_ = before;
    set_horizon_shift(rows);
    process(grey, true);
    measured = lanes_.measure_shift();
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
  lanes_.clear();
  return {};
}

void MarkingDetector::set_horizon_shift(int rows) {
  rows = std::clamp(rows, -config_.horizon_max_shift_px, config_.horizon_max_shift_px);
  if (rows == birdseye_.row_shift()) return;
  birdseye_.set_row_shift(rows, config_.hidden_below_follows_horizon ? rows : 0);
  edges_.update(birdseye_);
  ++counters_.horizon_moves;
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
    paint_.clear();
    lanes_.clear();
    return;
  }
  find_candidates();
  for (std::size_t i = 0; i < candidate_count_; ++i)
    classifier_.classify(bev_, paint_.mask(), candidates_[i]);
  const std::span<std::int32_t> reported_by{reported_by_.data(), candidate_count_};
  const std::size_t joined = words_.join(candidates(), reported_by) +
                             crosswalks_.join({candidates_.data(), candidate_count_}, reported_by);
  counters_.joined += joined;
  report(still, joined > 0);
}

void MarkingDetector::find_candidates() {
  // Parts or candidates dropped at the caps in this frame make it cluttered.
  const std::uint64_t dropped_before = counters_.parts_dropped + counters_.candidates_dropped;
  paint_.find(bev_, birdseye_.valid(), edges_.valid_integral());
  lanes_.clear();
  labeller_.label(paint_.mask(), config_.horizon_from_lanes ? &lanes_ : nullptr, counters_);
  candidate_count_ = grouper_.group(labeller_.parts(), labeller_.strokes(), candidates_, counters_);
  if (counters_.parts_dropped + counters_.candidates_dropped > dropped_before)
    last_view_ = ViewKind::Cluttered;
}

void MarkingDetector::report(bool still, bool any_joined) {
  const std::span<const std::int32_t> reported_by{reported_by_.data(), candidate_count_};
  for (std::size_t i = 0; i < candidate_count_; ++i) {
    if (reported_by_[i] != static_cast<std::int32_t>(i)) {                 // in a word's detection
      if (candidates_[i].predicted == kRejectClass) ++counters_.rejected;  // a broken letter
      continue;
    }
    // The first of a word's candidates split by its I reports the word.
    const bool first_of_word = any_joined && reports_others(reported_by, i);
    Candidate word;  // filled only for a word: a copy, as rare as they are
    if (first_of_word) word = joined_candidate(candidates(), reported_by, i);
    const Candidate& candidate = first_of_word ? word : candidates_[i];
    const bool partial = candidate.clipped_near_only && still && config_.report_partial_in_stills;
    if (!reportable(candidate, i, partial)) continue;
    Detection& d = detections_[detection_count_++];
    d.label = static_cast<Label>(candidate.predicted);
    d.score = candidate.score;
    d.partial = partial;
    d.turned = candidate.turned;
    locator_.locate(candidate, d);
    ++counters_.detections;
    if (partial) ++counters_.partial;
  }
}

bool MarkingDetector::reportable(const Candidate& candidate, std::size_t i, bool partial) {
  const auto withheld = [](std::uint64_t& counter) {
    ++counter;
    return false;
  };
  if (candidate.predicted == kRejectClass) return withheld(counters_.rejected);
  // Parts too large to group (a railway X) are never grouped with the
  // pieces inside them; reported, a piece would be a second landmark.
  if (is_piece_of_larger(candidates(), i)) return withheld(counters_.pieces);
  if (candidate.clipped && !config_.report_clipped && !partial) return withheld(counters_.clipped);
  if (locator_.beyond_region(candidate)) return withheld(counters_.beyond_region);
  if (candidate.score < config_.min_score) return withheld(counters_.low_score);
  // Examined in part only, up to the caps: what it found is no more
  // trustworthy than what it left out.
  if (last_view_ == ViewKind::Cluttered) return withheld(counters_.detections_withheld);
  if (detection_count_ == kMaxDetections) return withheld(counters_.detections_dropped);
  return true;
}

bool is_piece_of_larger(std::span<const Candidate> candidates, std::size_t index) {
  const Candidate& c = candidates[index];
  for (std::size_t j = 0; j < candidates.size(); ++j) {
    const Candidate& outer = candidates[j];
    if (j == index || (outer.predicted != c.predicted && !outer.clipped)) continue;
    const int shared_cols = cols_shared(c, outer);
    const int shared_rows = rows_shared(c, outer);
    if (shared_cols <= 0 || shared_rows <= 0) continue;
    const int area = cols_of(c) * rows_of(c);
    const bool mostly_inside =
        static_cast<float>(shared_cols * shared_rows) >= kPieceMinInside * static_cast<float>(area);
    const bool larger = cols_of(outer) * rows_of(outer) > area;
    if (mostly_inside && larger) return true;
  }
  return false;
}

}  // namespace markloop::perception
