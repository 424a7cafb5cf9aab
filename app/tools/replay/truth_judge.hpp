// Judges loop detections against the simulator's ground truth (one true pose
// per frame). Shared by markloop-replay (matches from the engine) and
// markloop-eval (matches read back from the ECU's CAN output).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "app/engine/types.hpp"

namespace markloop::replay {

// A revisited 100 m stretch without a correct detection, and where its
// revisiting frames were first driven (to tell a miss of the detector from a
// stretch whose first visit came before any sequence could exist).
struct MissedStretch {
  std::uint64_t index = 0;                      // stretch i covers [100 i, 100 (i + 1)) m of the drive
  std::size_t first_frame = 0, last_frame = 0;  // its revisiting frames
  std::size_t first_visit_from = 0, first_visit_to = 0;  // the earlier frames they revisit
};

struct Evaluation {
  std::size_t correct = 0;
  std::size_t wrong = 0;
  std::size_t unjudged = 0;          // a frame beyond the truth file
  std::size_t revisit_segments = 0;  // 100 m stretches of road driven before
  std::size_t revisit_segments_detected = 0;
  std::vector<MissedStretch> missed_stretches;
  // Relative pose error of the correct matches that carry a relative pose.
  std::size_t pose_errors = 0;
  double translation_error_mean_m = 0.0;
  double translation_error_max_m = 0.0;
  double rotation_error_mean_deg = 0.0;
  double rotation_error_max_deg = 0.0;
};

struct FramePair {
  FrameIndex query = 0;
  FrameIndex match = 0;
};

struct PoseError {
  double translation_m = 0.0;
  double rotation_deg = 0.0;
};

class TruthJudge {
 public:
  // A match is correct when the true positions of its two frames are within
  // `radius_m`. A revisit is a frame within `radius_m` of the true position
  // of a frame at least `min_separation_m` earlier along the drive.
  TruthJudge(std::vector<Pose2> truth, double radius_m, double min_separation_m);

  bool covers(FrameIndex frame) const { return frame < truth_.size(); }
  bool correct(const FramePair& pair) const;
  // The true pose of the car at the query in the car's frame at the match:
  // inverse(truth[match]) o truth[query] (MatchEvent::relative_pose's
  // convention). Precondition: covers() both frames.
  Pose2 true_relative_pose(const FramePair& pair) const;
  PoseError pose_error(const FramePair& pair, const Pose2& estimated_relative_pose) const;
  // `relative_poses` is empty, or holds per pair the estimated relative pose
  // when the match carries one.
  Evaluation evaluate(const std::vector<FramePair>& pairs,
                      std::span<const std::optional<Pose2>> relative_poses = {}) const;

  const std::vector<Pose2>& truth() const { return truth_; }
  double radius_m() const { return radius_m_; }

 private:
  std::vector<Pose2> truth_;
  double radius_m_;
  std::vector<bool> revisit_;                 // per frame
  std::vector<std::size_t> revisited_frame_;  // per revisiting frame: the earlier frame it revisits
  std::vector<std::uint64_t> segment_;        // per frame: index of its 100 m stretch
};

}  // namespace markloop::replay
