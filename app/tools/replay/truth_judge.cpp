#include "app/tools/replay/truth_judge.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <unordered_map>

#include "app/common/units.hpp"

namespace markloop::replay {

namespace {

constexpr double kSegmentLength_m = 100.0;

struct Stretch {
  MissedStretch missed;  // where it lies, should no correct match fall in it
  bool detected = false;
};

}  // namespace

TruthJudge::TruthJudge(std::vector<Pose2> truth, double radius_m, double min_separation_m)
    : truth_(std::move(truth)), radius_m_(radius_m) {
  // Travelled distance per frame, then a grid of cell size `radius` to find
  // earlier frames nearby.
  std::vector<double> travelled(truth_.size(), 0.0);
  for (std::size_t i = 1; i < truth_.size(); ++i)
    travelled[i] =
        travelled[i - 1] + std::hypot(truth_[i].x - truth_[i - 1].x, truth_[i].y - truth_[i - 1].y);
  const auto cell = [&](double v) { return static_cast<std::int64_t>(std::floor(v / radius_m_)); };
  const auto key = [](std::int64_t cx, std::int64_t cy) { return cx * 2654435761LL + cy; };
  std::unordered_map<std::int64_t, std::vector<std::size_t>> grid;
  revisit_.assign(truth_.size(), false);
  revisited_frame_.assign(truth_.size(), 0);
  segment_.resize(truth_.size());
  for (std::size_t i = 0; i < truth_.size(); ++i) {
    segment_[i] = static_cast<std::uint64_t>(travelled[i] / kSegmentLength_m);
    const std::int64_t cx = cell(truth_[i].x), cy = cell(truth_[i].y);
    for (std::int64_t dx = -1; dx <= 1 && !revisit_[i]; ++dx) {
      for (std::int64_t dy = -1; dy <= 1 && !revisit_[i]; ++dy) {
        const auto it = grid.find(key(cx + dx, cy + dy));
        if (it == grid.end()) continue;
        // Frames of a cell in drive order, so travelled distance rises
        // along it: only its first ones lie far enough back.
        const std::vector<std::size_t>& earlier = it->second;
        const auto far_back = std::partition_point(earlier.begin(), earlier.end(), [&](std::size_t j) {
          return travelled[i] - travelled[j] >= min_separation_m;
        });
        for (auto j = earlier.begin(); j != far_back; ++j) {
          if (std::hypot(truth_[i].x - truth_[*j].x, truth_[i].y - truth_[*j].y) <= radius_m_) {
            revisit_[i] = true;
            revisited_frame_[i] = *j;
            break;
          }
        }
      }
    }
    grid[key(cx, cy)].push_back(i);
  }
}

bool TruthJudge::correct(const FramePair& pair) const {
  const Pose2& a = truth_.at(pair.query);
  const Pose2& b = truth_.at(pair.match);
  return std::hypot(a.x - b.x, a.y - b.y) <= radius_m_;
}

Pose2 TruthJudge::true_relative_pose(const FramePair& pair) const {
  return compose(inverse(truth_.at(pair.match)), truth_.at(pair.query));
}

PoseError TruthJudge::pose_error(const FramePair& pair, const Pose2& estimate) const {
  const Pose2 truth_relative = true_relative_pose(pair);
  return {std::hypot(estimate.x - truth_relative.x, estimate.y - truth_relative.y),
          std::abs(wrap_angle(estimate.yaw - truth_relative.yaw)) * kDegreesPerRadian};
}

Evaluation TruthJudge::evaluate(const std::vector<FramePair>& pairs,
                                std::span<const std::optional<Pose2>> relative_poses) const {
  Evaluation e;
  // The revisited stretches, by index, and their revisiting frames: as many
  // as there are frames at most, however long the stretches' indices run.
  std::map<std::uint64_t, Stretch> revisited;
  for (std::size_t i = 0; i < truth_.size(); ++i) {
    if (!revisit_[i]) continue;
    const auto [it, first] = revisited.try_emplace(segment_[i]);
    MissedStretch& m = it->second.missed;
    if (first) {
      m.index = segment_[i];
      m.first_frame = i;
      m.first_visit_from = m.first_visit_to = revisited_frame_[i];
    }
    m.last_frame = i;
    m.first_visit_from = std::min(m.first_visit_from, revisited_frame_[i]);
    m.first_visit_to = std::max(m.first_visit_to, revisited_frame_[i]);
  }

  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const FramePair& pair = pairs[i];
    if (!covers(pair.query) || !covers(pair.match)) {
      ++e.unjudged;
      continue;
    }
    if (!correct(pair)) {
      ++e.wrong;
      continue;
    }
    ++e.correct;
    if (const auto it = revisited.find(segment_[pair.query]); it != revisited.end())
      it->second.detected = true;
    if (i >= relative_poses.size() || !relative_poses[i]) continue;
    const PoseError error = pose_error(pair, *relative_poses[i]);
    ++e.pose_errors;
    e.translation_error_mean_m += error.translation_m;
    e.rotation_error_mean_deg += error.rotation_deg;
    e.translation_error_max_m = std::max(e.translation_error_max_m, error.translation_m);
    e.rotation_error_max_deg = std::max(e.rotation_error_max_deg, error.rotation_deg);
  }
  if (e.pose_errors > 0) {
    e.translation_error_mean_m /= static_cast<double>(e.pose_errors);
    e.rotation_error_mean_deg /= static_cast<double>(e.pose_errors);
  }
  for (const auto& [index, stretch] : revisited) {
    ++e.revisit_segments;
    if (stretch.detected)
      ++e.revisit_segments_detected;
    else
      e.missed_stretches.push_back(stretch.missed);
  }
  return e;
}

}  // namespace markloop::replay
