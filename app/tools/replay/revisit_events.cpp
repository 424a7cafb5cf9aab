#include "app/tools/replay/revisit_events.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <unordered_map>

#include "app/common/units.hpp"

namespace markloop::replay {

namespace {

// What each frame is: not a revisit, or a revisit of one kind.
using FrameKind = std::optional<RevisitKind>;

std::vector<double> travelled_distances(std::span<const Pose2> poses) {
  std::vector<double> travelled(poses.size(), 0.0);
  for (std::size_t i = 1; i < poses.size(); ++i)
    travelled[i] = travelled[i - 1] + std::hypot(poses[i].x - poses[i - 1].x, poses[i].y - poses[i - 1].y);
  return travelled;
}

// The kind of a frame near an older one with heading difference `yaw_a - yaw_b`.
RevisitKind kind_of_heading(double yaw_a, double yaw_b) {
  const double difference_deg = std::abs(wrap_angle(yaw_a - yaw_b)) * kDegreesPerRadian;
  if (difference_deg <= kAlongRoadTolerance_deg) return RevisitKind::SameDirection;
  if (difference_deg >= 180.0 - kAlongRoadTolerance_deg) return RevisitKind::OppositeDirection;
  return RevisitKind::Crossing;
}

// Per frame: its kind when it revisits an older frame. Older frames nearby
// are looked up in a grid of kRevisitRadius_m cells; of several, the one
// that puts the car along the old road wins (same, then opposite).
std::vector<FrameKind> revisit_frame_kinds(std::span<const Pose2> poses, std::span<const double> times) {
  const auto cell = [](double v) { return static_cast<std::int64_t>(std::floor(v / kRevisitRadius_m)); };
  const auto key = [](std::int64_t cx, std::int64_t cy) { return cx * 2654435761LL + cy; };
  std::unordered_map<std::int64_t, std::vector<std::size_t>> grid;
  std::vector<FrameKind> kinds(poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const std::int64_t cx = cell(poses[i].x), cy = cell(poses[i].y);
    FrameKind& kind = kinds[i];
    for (std::int64_t dx = -1; dx <= 1; ++dx) {
      for (std::int64_t dy = -1; dy <= 1; ++dy) {
        const auto it = grid.find(key(cx + dx, cy + dy));
        if (it == grid.end()) continue;
        // A cell's frames are in time order: the old enough ones come first.
        const std::vector<std::size_t>& earlier = it->second;
        const auto old_enough = std::partition_point(earlier.begin(), earlier.end(), [&](std::size_t j) {
          return times[i] - times[j] >= kRevisitMinAge_s;
        });
        for (auto j = earlier.begin(); j != old_enough && kind != RevisitKind::SameDirection; ++j) {
          if (std::hypot(poses[i].x - poses[*j].x, poses[i].y - poses[*j].y) > kRevisitRadius_m) continue;
          const RevisitKind k = kind_of_heading(poses[i].yaw, poses[*j].yaw);
          if (!kind || static_cast<int>(k) < static_cast<int>(*kind)) kind = k;
        }
      }
    }
    grid[key(cx, cy)].push_back(i);
  }
  return kinds;
}

// The event's kind by the distance its revisit frames of each kind cover
// (each the step to the next frame, the last one the step from the one
// before; frames counted when the car stood still).
RevisitKind event_kind(std::span<const FrameKind> kinds, const std::vector<double>& travelled,
                       std::size_t first, std::size_t last) {
  std::array<double, kRevisitKindCount> distance{}, frames{};
  for (std::size_t i = first; i <= last; ++i) {
    if (!kinds[i]) continue;
    const auto k = static_cast<std::size_t>(*kinds[i]);
    if (i < last)
      distance[k] += travelled[i + 1] - travelled[i];
    else if (i > first)
      distance[k] += travelled[i] - travelled[i - 1];
    frames[k] += 1.0;
  }
  double total = 0.0;
  for (const double d : distance) total += d;
  const auto& weight = total > 0.0 ? distance : frames;
  if (total <= 0.0) total = frames[0] + frames[1] + frames[2];
  for (const RevisitKind k : {RevisitKind::SameDirection, RevisitKind::OppositeDirection})
    if (weight[static_cast<std::size_t>(k)] > 0.5 * total) return k;
  return RevisitKind::Crossing;
}

bool seen(const MarkingView& v) {
  return v.ahead_m >= kSeenNearest_m && v.ahead_m <= kSeenFarthest_m && std::abs(v.left_m) <= kSeenSide_m;
}

// The views of markings seen, in frame order, and the first frame each
// marking was seen.
struct SeenMarkings {
  std::vector<MarkingView> views;
  std::unordered_map<std::uint32_t, std::size_t> first_frame;
};

SeenMarkings seen_markings(std::span<const MarkingView> views, std::size_t frames) {
  SeenMarkings s;
  for (const MarkingView& v : views) {
    if (v.frame >= frames || !seen(v)) continue;
    s.views.push_back(v);
    const auto [it, added] = s.first_frame.try_emplace(v.marking, v.frame);
    if (!added) it->second = std::min(it->second, v.frame);
  }
  std::stable_sort(s.views.begin(), s.views.end(),
                   [](const MarkingView& a, const MarkingView& b) { return a.frame < b.frame; });
  return s;
}

// The frame at which each marking seen in frames `from` to `to` and already
// seen kRevisitMinAge_s before `event_start_s` was passed: the last frame of
// its first run of sightings there (a long event may pass it again).
std::vector<std::size_t> first_passes(const SeenMarkings& seen, std::span<const double> times,
                                      std::size_t from, std::size_t to, double event_start_s) {
  struct Pass {
    std::size_t last = 0;
    bool over = false;
  };
  std::unordered_map<std::uint32_t, Pass> passes;
  const auto first = std::lower_bound(seen.views.begin(), seen.views.end(), from,
                                      [](const MarkingView& v, std::size_t f) { return v.frame < f; });
  for (auto v = first; v != seen.views.end() && v->frame <= to; ++v) {
    if (times[seen.first_frame.at(v->marking)] > event_start_s - kRevisitMinAge_s) continue;
    const auto [it, added] = passes.try_emplace(v->marking, Pass{v->frame, false});
    Pass& p = it->second;
    if (added || p.over) continue;
    if (times[v->frame] - times[p.last] < kRevisitMaxGap_s)
      p.last = v->frame;
    else
      p.over = true;
  }
  std::vector<std::size_t> frames;
  for (const auto& [marking, p] : passes) frames.push_back(p.last);
  return frames;
}

// The first frame of an event's lead: kSharedLead_m before its first.
std::size_t lead_frame(const std::vector<double>& travelled, std::size_t first_frame) {
  const auto begin = travelled.begin(), end = begin + static_cast<std::ptrdiff_t>(first_frame);
  return static_cast<std::size_t>(std::lower_bound(begin, end, travelled[first_frame] - kSharedLead_m) -
                                  begin);
}

// The shared markings passed at `pass_frames` (any order).
SharedMarkings shared_at(std::span<const std::size_t> pass_frames, const std::vector<double>& travelled,
                         std::size_t first_frame) {
  std::vector<double> at;
  for (const std::size_t frame : pass_frames)
    at.push_back(std::max(0.0, travelled[frame] - travelled[first_frame]));
  std::sort(at.begin(), at.end());
  SharedMarkings shared;
  shared.count = at.size();
  if (at.size() >= 2) shared.second_m = at[1];
  if (at.size() >= 3) shared.third_m = at[2];
  return shared;
}

void add_shared(const std::optional<SharedMarkings>& shared, std::vector<double>& second,
                std::vector<double>& third, SharedTally& tally) {
  if (!shared) return;
  ++tally.known;
  if (shared->second_m) second.push_back(*shared->second_m);
  if (shared->third_m) third.push_back(*shared->third_m);
}

ClosureDistances closure_distances(std::vector<double> values) {
  ClosureDistances d;
  d.count = values.size();
  if (values.empty()) return d;
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  d.median_m = n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
  const auto rank = static_cast<std::size_t>(std::ceil(0.9 * static_cast<double>(n)));
  d.p90_m = values[std::max<std::size_t>(rank, 1) - 1];
  return d;
}

void count(RevisitCount& c, const RevisitEvent& e) {
  ++c.total;
  if (e.closed_at_m) ++c.closed;
}

}  // namespace

std::string_view revisit_kind_name(RevisitKind kind) {
  switch (kind) {
    case RevisitKind::SameDirection:
      return "same";
    case RevisitKind::OppositeDirection:
      return "opposite";
    case RevisitKind::Crossing:
      return "crossing";
  }
  return "?";
}

std::optional<RevisitKind> revisit_kind_from_name(std::string_view name) {
  for (const RevisitKind k :
       {RevisitKind::SameDirection, RevisitKind::OppositeDirection, RevisitKind::Crossing})
    if (revisit_kind_name(k) == name) return k;
  return std::nullopt;
}

std::vector<RevisitEvent> find_revisit_events(std::span<const Pose2> poses, std::span<const double> times) {
  const std::vector<FrameKind> kinds = revisit_frame_kinds(poses, times);
  const std::vector<double> travelled = travelled_distances(poses);
  std::vector<RevisitEvent> events;
  std::optional<std::size_t> first, last;
  const auto finish = [&] {
    RevisitEvent e;
    e.first_frame = *first;
    e.last_frame = *last;
    e.start_m = travelled[*first];
    e.length_m = travelled[*last] - travelled[*first];
    e.kind = event_kind(kinds, travelled, *first, *last);
    events.push_back(e);
  };
  for (std::size_t i = 0; i < kinds.size(); ++i) {
    if (!kinds[i]) continue;
    if (last && times[i] - times[*last] >= kRevisitMaxGap_s) finish(), first.reset();
    if (!first) first = i;
    last = i;
  }
  if (first) finish();
  return events;
}

void close_revisit_events(std::vector<RevisitEvent>& events, std::span<const Pose2> poses,
                          std::span<const ClosingDetection> detections) {
  const std::vector<double> travelled = travelled_distances(poses);
  for (const ClosingDetection& d : detections) {
    if (!d.correct || d.query_frame >= poses.size()) continue;
    // Events are in drive order and do not overlap: the last one starting
    // at or before the query frame is the only one that may hold it.
    const auto after =
        std::upper_bound(events.begin(), events.end(), d.query_frame,
                         [](std::size_t f, const RevisitEvent& e) { return f < e.first_frame; });
    if (after == events.begin()) continue;
    RevisitEvent& e = *(after - 1);
    if (d.query_frame > e.last_frame) continue;
    const std::size_t bus_frame = std::min(std::max(d.bus_frame, e.first_frame), poses.size() - 1);
    const double at_m = travelled[bus_frame] - travelled[e.first_frame];
    if (!e.closed_at_m || at_m < *e.closed_at_m) {
      e.closed_at_m = at_m;
      e.closing_query_frame = d.query_frame;
    }
  }
}

void mark_shared_markings(std::vector<RevisitEvent>& events, std::span<const Pose2> poses,
                          std::span<const double> times, std::span<const MarkingView> views) {
  const std::size_t frames = std::min(poses.size(), times.size());
  const SeenMarkings seen = seen_markings(views, frames);
  const std::vector<double> travelled = travelled_distances(poses.first(frames));
  for (RevisitEvent& e : events) {
    if (e.last_frame >= frames || e.first_frame > e.last_frame) continue;
    e.seen = shared_at(
        first_passes(seen, times, lead_frame(travelled, e.first_frame), e.last_frame, times[e.first_frame]),
        travelled, e.first_frame);
  }
}

void mark_landmarked_markings(std::vector<RevisitEvent>& events, std::span<const Pose2> poses,
                              std::span<const double> times, std::span<const LandmarkedPass> passes) {
  const std::size_t frames = std::min(poses.size(), times.size());
  const std::vector<double> travelled = travelled_distances(poses.first(frames));
  // Per marking and label, the frame the first pass naming it so ended at.
  const auto key = [](const LandmarkedPass& p) { return (std::uint64_t{p.marking} << 32) | p.label; };
  std::unordered_map<std::uint64_t, std::size_t> first_named;
  for (const LandmarkedPass& p : passes) {
    if (p.last_frame >= frames) continue;
    const auto [it, added] = first_named.try_emplace(key(p), p.last_frame);
    if (!added) it->second = std::min(it->second, p.last_frame);
  }
  for (RevisitEvent& e : events) {
    if (e.last_frame >= frames || e.first_frame > e.last_frame) continue;
    const std::size_t from = lead_frame(travelled, e.first_frame);
    const double older_s = times[e.first_frame] - kRevisitMinAge_s;
    // Per marking, the first pass in the event (or its lead) whose label an
    // older pass gave too.
    std::unordered_map<std::uint32_t, std::size_t> first_pass;
    for (const LandmarkedPass& p : passes) {
      if (p.last_frame < from || p.last_frame > e.last_frame) continue;
      if (times[first_named.at(key(p))] > older_s) continue;
      const auto [it, added] = first_pass.try_emplace(p.marking, p.last_frame);
      if (!added) it->second = std::min(it->second, p.last_frame);
    }
    std::vector<std::size_t> pass_frames;
    for (const auto& [marking, frame] : first_pass) pass_frames.push_back(frame);
    e.landmarked = shared_at(pass_frames, travelled, e.first_frame);
  }
}

RevisitTally tally_revisit_events(std::span<const RevisitEvent> events) {
  RevisitTally t;
  std::vector<double> closure_long, closure_all;
  std::vector<double> seen_second, seen_third, landmarked_second, landmarked_third, beyond_third;
  for (const RevisitEvent& e : events) {
    const bool long_event = e.length_m >= kLongRevisit_m;
    count(t.by_kind[static_cast<std::size_t>(e.kind)][long_event ? 1 : 0], e);
    count(long_event ? t.longer : t.shorter, e);
    count(t.all, e);
    if (long_event) {
      add_shared(e.seen, seen_second, seen_third, t.seen_long);
      add_shared(e.landmarked, landmarked_second, landmarked_third, t.landmarked_long);
    }
    if (!e.closed_at_m) continue;
    closure_all.push_back(*e.closed_at_m);
    if (!long_event) continue;
    closure_long.push_back(*e.closed_at_m);
    if (e.landmarked && e.landmarked->third_m)
      beyond_third.push_back(*e.closed_at_m - *e.landmarked->third_m);
  }
  t.closure_long = closure_distances(std::move(closure_long));
  t.closure_all = closure_distances(std::move(closure_all));
  t.seen_long.second = closure_distances(std::move(seen_second));
  t.seen_long.third = closure_distances(std::move(seen_third));
  t.landmarked_long.second = closure_distances(std::move(landmarked_second));
  t.landmarked_long.third = closure_distances(std::move(landmarked_third));
  t.beyond_third_landmarked_long = closure_distances(std::move(beyond_third));
  return t;
}

}  // namespace markloop::replay
