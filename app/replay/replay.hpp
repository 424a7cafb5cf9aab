// Runs the sequence engine over recorded detections, and judges matches
// against ground truth.
#pragma once

#include <vector>

#include "engine/sequence_engine.hpp"
#include "replay/paper_format.hpp"

namespace markloop::replay {

struct ReplayResult {
  std::vector<MatchEvent> matches;
  EngineCounters counters;
  TrackerCounters tracker;
  DatabaseStats database;
  std::size_t frames = 0;
};

// Feeds every frame from 0 to the last one seen (in the markings or the
// poses) to a fresh engine. Records are taken in frame order (stable).
// `poses` may be empty: the engine then works without odometry.
ReplayResult run_engine(const std::vector<MarkingRecord>& records, const std::vector<Pose2>& poses,
                        LabelTable& labels, const EngineConfig& config, double fps);

struct Evaluation {
  std::size_t correct = 0;
  std::size_t wrong = 0;
  std::size_t unjudged = 0;          // a frame beyond the truth file
  std::size_t revisit_segments = 0;  // 100 m stretches of road driven before
  std::size_t revisit_segments_detected = 0;
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

class TruthJudge {
 public:
  // A match is correct when the true positions of its two frames are within
  // `radius_m`. A revisit is a frame within `radius_m` of the true position
  // of a frame at least `min_separation_m` earlier along the drive.
  TruthJudge(std::vector<Pose2> truth, double radius_m, double min_separation_m);

  bool covers(FrameIndex frame) const { return frame < truth_.size(); }
  bool correct(const FramePair& pair) const;
  Evaluation evaluate(const std::vector<FramePair>& pairs,
                      const std::vector<MatchEvent>* events = nullptr) const;

 private:
  std::vector<Pose2> truth_;
  double radius_m_;
  std::vector<bool> revisit_;          // per frame
  std::vector<std::size_t> segment_;   // per frame: index of its 100 m stretch
};

std::vector<FramePair> frame_pairs(const std::vector<MatchEvent>& events);

}  // namespace markloop::replay
