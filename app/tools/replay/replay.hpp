// Runs the sequence engine over recorded detections (judged against ground
// truth by TruthJudge, truth_judge.hpp).
#pragma once

#include <optional>
#include <vector>

#include "app/engine/sequence_engine.hpp"
#include "app/tools/replay/paper_format.hpp"
#include "app/tools/replay/truth_judge.hpp"

namespace markloop::replay {

struct ReplayResult {
  std::vector<MatchEvent> matches;
  // Per match: the frame the engine was processing when it emitted it (the
  // last frame fed for the matches of the final flush).
  std::vector<FrameIndex> emitted_at;
  EngineCounters counters;
  PlaceCounters places;
  TrackerCounters tracker;
  std::optional<ScaleEstimate> odometry_scale;  // the camera's measure (odometry_scale.hpp)
  DatabaseStats database;
  std::size_t frames = 0;
};

// Feeds every frame from 0 to the last one seen (in the markings or the
// poses) to a fresh engine. Records are taken in frame order (stable).
// `poses` may be empty: the engine then works without odometry.
ReplayResult run_engine(const std::vector<MarkingRecord>& records, const std::vector<Pose2>& poses,
                        LabelTable& labels, const EngineConfig& config, double fps);

std::vector<FramePair> frame_pairs(const std::vector<MatchEvent>& events);
// Per event its relative pose when it carries one (for TruthJudge::evaluate).
std::vector<std::optional<Pose2>> relative_poses(const std::vector<MatchEvent>& events);

}  // namespace markloop::replay
