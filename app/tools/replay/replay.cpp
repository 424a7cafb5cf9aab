#include "app/tools/replay/replay.hpp"

#include <algorithm>
#include <cmath>
#include <memory>

namespace markloop::replay {

namespace {

// Collects the matches and the frame being processed when each came.
class CollectingSink final : public MatchSink {
 public:
  explicit CollectingSink(ReplayResult& result) : result_(result) {}
  void on_match(const MatchEvent& event) override {
    result_.matches.push_back(event);
    result_.emitted_at.push_back(frame);
  }
  FrameIndex frame = 0;

 private:
  ReplayResult& result_;
};

// The first frame after `seen` and before `frame_count` at which a track
// last seen in `seen` is committed (the engine's own test, now - t_last >
// commit_after_s, on the same frame times), or `frame_count` when none is.
std::size_t commit_frame(std::size_t seen, std::size_t frame_count, double commit_after_s, double fps) {
  const double t_seen = static_cast<double>(seen) / fps;
  const auto committed = [&](std::size_t f) {
    return static_cast<double>(f) / fps - t_seen > commit_after_s;
  };
  if (seen + 1 >= frame_count || !committed(frame_count - 1)) return frame_count;
  // The test only turns true as frames go on: the first frame it holds for.
  std::size_t low = seen + 1, high = frame_count - 1;
  while (low < high) {
    const std::size_t middle = low + (high - low) / 2;
    if (committed(middle))
      high = middle;
    else
      low = middle + 1;
  }
  return low;
}

// The frames to feed, in order: every frame with a pose (the odometry needs
// each), every frame with detections, and the frame at which each of their
// tracks would be committed. Any other frame carries nothing and changes
// nothing in the engine, so leaving it out gives the same matches in time
// that follows the records, not the frame numbers.
std::vector<std::size_t> frames_to_feed(const std::vector<const MarkingRecord*>& ordered,
                                        std::size_t pose_count, std::size_t frame_count,
                                        double commit_after_s, double fps) {
  std::vector<std::size_t> fed;
  for (std::size_t i = 0; i < ordered.size(); ++i) {
    const auto f = static_cast<std::size_t>(ordered[i]->frame);
    if (i > 0 && ordered[i - 1]->frame == ordered[i]->frame) continue;
    fed.push_back(f);
    const std::size_t commit = commit_frame(f, frame_count, commit_after_s, fps);
    if (commit < frame_count) fed.push_back(commit);
  }
  std::sort(fed.begin(), fed.end());
  const auto with_pose = std::lower_bound(fed.begin(), fed.end(), pose_count);
  fed.erase(fed.begin(), with_pose);
  fed.erase(std::unique(fed.begin(), fed.end()), fed.end());
  std::vector<std::size_t> all(pose_count);
  for (std::size_t f = 0; f < pose_count; ++f) all[f] = f;
  all.insert(all.end(), fed.begin(), fed.end());
  return all;
}

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
  CollectingSink sink(result);
  std::vector<Observation> observations;
  std::size_t next = 0;
  for (const std::size_t f :
       frames_to_feed(ordered, poses.size(), frames, config.tracker.commit_after_s, fps)) {
    observations.clear();
    for (; next < ordered.size() && ordered[next]->frame == static_cast<std::int32_t>(f); ++next)
      observations.push_back(to_ground(*ordered[next], labels.intern(ordered[next]->label)));
    FrameInput input{static_cast<FrameIndex>(f), static_cast<double>(f) / fps, f < poses.size(),
                     f < poses.size() ? poses[f] : Pose2{}};
    sink.frame = input.frame;
    engine->process_frame(input, observations, sink);
  }
  engine->flush(sink);
  result.counters = engine->counters();
  result.places = engine->place_counters();
  result.tracker = engine->tracker_counters();
  result.odometry_scale = engine->odometry_scale().estimate();
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
