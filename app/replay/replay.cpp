#include "replay/replay.hpp"

#include <algorithm>
#include <cmath>
#include <memory>

namespace markloop::replay {

namespace {

class CollectingSink final : public MatchSink {
 public:
  explicit CollectingSink(std::vector<MatchEvent>& events) : events_(events) {}
  void on_match(const MatchEvent& event) override { events_.push_back(event); }

 private:
  std::vector<MatchEvent>& events_;
};

}  // namespace

ReplayResult run_engine(const std::vector<MarkingRecord>& records, const std::vector<Pose2>& poses,
                        LabelTable& labels, const EngineConfig& config, double fps) {
  std::vector<const MarkingRecord*> ordered;
  ordered.reserve(records.size());
  for (const MarkingRecord& r : records) ordered.push_back(&r);
  std::stable_sort(ordered.begin(), ordered.end(),
                   [](const MarkingRecord* a, const MarkingRecord* b) { return a->frame < b->frame; });

  std::size_t frames = poses.size();
  if (!ordered.empty()) frames = std::max<std::size_t>(frames, ordered.back()->frame + 1u);

  ReplayResult result;
  result.frames = frames;
  auto engine = std::make_unique<SequenceEngine>(config);
  CollectingSink sink(result.matches);
  std::vector<Observation> observations;
  std::size_t next = 0;
  for (std::size_t f = 0; f < frames; ++f) {
    observations.clear();
    for (; next < ordered.size() && ordered[next]->frame == static_cast<std::int32_t>(f); ++next)
      observations.push_back(to_ground(*ordered[next], labels.intern(ordered[next]->label)));
    FrameInput input{static_cast<FrameIndex>(f), static_cast<double>(f) / fps, f < poses.size(),
                     f < poses.size() ? poses[f] : Pose2{}};
    engine->process_frame(input, observations, sink);
  }
  engine->flush(sink);
  result.counters = engine->counters();
  result.tracker = engine->tracker_counters();
  result.database = engine->database().stats();
  return result;
}

std::vector<FramePair> frame_pairs(const std::vector<MatchEvent>& events) {
  std::vector<FramePair> pairs;
  pairs.reserve(events.size());
  for (const MatchEvent& e : events) pairs.push_back({e.query_frame(), e.match_frame()});
  return pairs;
}

std::vector<std::optional<Pose2>> relative_poses(const std::vector<MatchEvent>& events) {
  std::vector<std::optional<Pose2>> poses;
  poses.reserve(events.size());
  for (const MatchEvent& e : events)
    poses.push_back(e.has_relative_pose ? std::optional<Pose2>(e.relative_pose) : std::nullopt);
  return poses;
}

}  // namespace markloop::replay
