#include "app/tools/eval/scoring.hpp"
#include "app/common/units.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>
#include <unordered_map>

#include <opencv2/imgproc.hpp>

namespace markloop::eval {

namespace {

std::vector<cv::Point2f> hull_of(const Quad& quad) {
  std::vector<cv::Point2f> points, hull;
  for (const auto& corner : quad)
    points.emplace_back(static_cast<float>(corner[0]), static_cast<float>(corner[1]));
  cv::convexHull(points, hull);
  return hull;
}

}  // namespace

Spread spread_of(std::vector<double> values) {
  Spread s;
  s.count = values.size();
  if (values.empty()) return s;
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  s.median = n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
  const auto rank = static_cast<std::size_t>(std::ceil(0.99 * static_cast<double>(n)));
  s.p99 = values[std::max<std::size_t>(rank, 1) - 1];
  s.max = values.back();
  s.min = values.front();
  return s;
}

std::vector<replay::ClosingDetection> closing_detections(const LoopScore& score,
                                                         const std::vector<LoopReport>& loops,
                                                         const std::vector<double>& frame_times) {
  std::vector<replay::ClosingDetection> closing;
  for (std::size_t i = 0; i < loops.size() && i < score.outcomes.size(); ++i) {
    const double stamp_s = static_cast<double>(loops[i].stamp_ns) * 1e-9;
    const auto after = std::upper_bound(frame_times.begin(), frame_times.end(), stamp_s + 1e-9);
    const std::size_t bus_frame =
        after == frame_times.begin() ? 0 : static_cast<std::size_t>(after - frame_times.begin()) - 1;
    const LoopOutcome& o = score.outcomes[i];
    closing.push_back({o.pair.query, bus_frame, o.verdict == Verdict::Correct});
  }
  return closing;
}

LoopScore score_loops(const replay::TruthJudge& judge, const std::vector<double>& frame_times,
                      const std::vector<LoopReport>& loops) {
  LoopScore score;
  std::vector<replay::FramePair> pairs;
  std::vector<std::optional<Pose2>> estimates;
  std::vector<double> latencies, processing, since_query_frame;
  for (const LoopReport& report : loops) {
    const dbc::LoopDetection& m = report.message;
    const replay::FramePair pair{m.query_frame, m.match_frame};
    const std::optional<Pose2> estimate =
        m.pose_valid
            ? std::optional<Pose2>(Pose2{m.pose_dx_m, m.pose_dy_m, m.pose_dyaw_deg * kRadiansPerDegree})
            : std::nullopt;
    pairs.push_back(pair);
    estimates.push_back(estimate);

    LoopOutcome outcome;
    outcome.pair = pair;
    const double stamp_s = static_cast<double>(report.stamp_ns) * 1e-9;
    outcome.latency_s = stamp_s - m.query_time_s;
    latencies.push_back(outcome.latency_s);
    // The latest frame that had arrived when the detection went out.
    const auto after = std::upper_bound(frame_times.begin(), frame_times.end(), stamp_s + 1e-9);
    if (after != frame_times.begin()) processing.push_back(stamp_s - *(after - 1));
    if (judge.covers(pair.query) && judge.covers(pair.match)) {
      const Pose2& a = judge.truth()[pair.query];
      const Pose2& b = judge.truth()[pair.match];
      outcome.true_distance_m = std::hypot(a.x - b.x, a.y - b.y);
      outcome.verdict = judge.correct(pair) ? Verdict::Correct : Verdict::Wrong;
      // For a wrong one too: a small error there says the markings were
      // the same and only the two frames lie apart (the routes parted).
      if (estimate) outcome.pose_error = judge.pose_error(pair, *estimate);
    }
    if (pair.query < frame_times.size()) {
      since_query_frame.push_back(stamp_s - frame_times[pair.query]);
      // QueryTime is the capture time of the frame that completed the
      // detection: never before QueryFrame, never after the send.
      if (m.query_time_s < frame_times[pair.query] - 0.0015 || m.query_time_s > stamp_s + 0.0015)
        ++score.query_time_inconsistent;
    }
    score.outcomes.push_back(outcome);
  }
  score.evaluation = judge.evaluate(pairs, estimates);
  score.latency_s = spread_of(std::move(latencies));
  score.processing_s = spread_of(std::move(processing));
  score.since_query_frame_s = spread_of(std::move(since_query_frame));
  return score;
}

namespace {

// The point (x, y) in `frame`'s own axes: x along its heading, y to its left.
Pose2 relative_to(const Pose2& frame, double x, double y) {
  return compose(inverse(frame), Pose2{x, y, 0.0});
}

// The marking's centre in the car's frame: metres ahead, metres to the left.
Pose2 in_car_frame(const WorldMarking& m, const Pose2& car) {
  return relative_to(car, m.x, m.y);
}

// From (x, y) to the marking, as score_landmarks measures it.
double distance_to(const WorldMarking& m, double x, double y, Label crosswalk) {
  const Pose2 p = relative_to(Pose2{m.x, m.y, m.heading}, x, y);
  double across = std::abs(p.y);
  if (m.label == crosswalk) across = std::max(0.0, across - kCrosswalkReach_m);
  return std::hypot(p.x, across);
}

bool in_region(const WorldMarking& m, const Pose2& car, const PassRegion& region) {
  const Pose2 p = in_car_frame(m, car);
  return p.x >= region.ahead_min_m && p.x <= region.ahead_max_m && std::abs(p.y) <= region.side_m;
}

}  // namespace

LandmarkScore score_landmarks(const std::vector<WorldMarking>& world, const std::vector<Pose2>& route,
                              const std::vector<LandmarkRecord>& landmarks) {
  const Label crosswalk = *perception::marking_class_from_name("crosswalk");
  LandmarkScore score;
  score.landmarks = landmarks.size();
  score.marking_of.assign(landmarks.size(), std::nullopt);
  std::vector<double> distances;
  for (std::size_t i = 0; i < landmarks.size(); ++i) {
    const LandmarkRecord& l = landmarks[i];
    if (!l.has_car_pose || l.last_frame >= route.size()) {
      ++score.without_pose;
      continue;
    }
    const Pose2 offset = relative_to(Pose2{l.car_x, l.car_y, l.car_yaw}, l.x, l.y);
    const Pose2 place = compose(route[l.last_frame], offset);
    MisplacedLandmark where{i, place.x, place.y, std::nullopt, std::numeric_limits<double>::infinity()};
    for (std::size_t m = 0; m < world.size(); ++m) {
      const double d = distance_to(world[m], place.x, place.y, crosswalk);
      if (d <= where.distance_m) {
        where.distance_m = d;
        where.nearest = m;
      }
    }
    if (where.distance_m <= kLandmarkOnMarking_m) score.marking_of[i] = where.nearest;
    if (!score.marking_of[i]) {
      ++score.on_nothing;
      score.misplaced.push_back(where);
      continue;
    }
    distances.push_back(where.distance_m);
    if (world[*score.marking_of[i]].label == l.label) {
      ++score.right_label;
    } else {
      ++score.wrong_label;
      score.misplaced.push_back(where);
    }
  }
  score.distance_m = spread_of(std::move(distances));
  return score;
}

namespace {

// The readers guarantee frames inside the route; anything else is not judged.
bool pass_inputs_consistent(const std::vector<Pose2>& route, const std::vector<double>& frame_times,
                            const std::vector<VisibleMarking>& truth,
                            const std::vector<DetectionRecord>& detections, const MarkingScore& markings,
                            const std::vector<LandmarkRecord>& landmarks, const LandmarkScore& placed) {
  if (frame_times.size() != route.size() || markings.paired_label.size() != truth.size() ||
      markings.detection_paired.size() != detections.size() || placed.marking_of.size() != landmarks.size())
    return false;
  for (const VisibleMarking& t : truth)
    if (t.frame >= route.size()) return false;
  for (const DetectionRecord& d : detections)
    if (d.frame >= route.size()) return false;
  return true;
}

// Judges the passes of the car by the world's markings, one run of visible
// rows of one marking at a time.
class PassJudge {
 public:
  PassJudge(const std::vector<WorldMarking>& world, const std::vector<Pose2>& route,
            const std::vector<double>& frame_times, const std::vector<VisibleMarking>& truth,
            const std::vector<DetectionRecord>& detections, const MarkingScore& markings,
            const std::vector<LandmarkRecord>& landmarks, const LandmarkScore& placed,
            const PassRegion& region)
      : world_(world),
        route_(route),
        times_(frame_times),
        truth_(truth),
        detections_(detections),
        markings_(markings),
        landmarks_(landmarks),
        region_(region),
        rows_(truth.size()),
        odometer_(route.size(), 0.0),
        // Unpaired detections on the ground where a marking lies, in the
        // frames visible.csv leaves it out of, are detections of it too.
        taken_(markings.detection_paired) {
    for (std::size_t i = 0; i < world.size(); ++i) world_index_.emplace(world[i].id, i);
    for (std::size_t i = 0; i < landmarks.size(); ++i)
      if (placed.marking_of[i]) landmarks_on_.emplace(*placed.marking_of[i], i);
    // The visible rows of each marking in frame order (truth is sorted by frame).
    for (std::size_t i = 0; i < rows_.size(); ++i) rows_[i] = i;
    std::stable_sort(rows_.begin(), rows_.end(),
                     [&](std::size_t a, std::size_t b) { return truth[a].id < truth[b].id; });
    for (std::size_t f = 1; f < route.size(); ++f)
      odometer_[f] = odometer_[f - 1] + std::hypot(route[f].x - route[f - 1].x, route[f].y - route[f - 1].y);
  }

  PassScore judge_all() {
    PassScore score;
    for (std::size_t begin = 0; begin < rows_.size();) {
      const std::size_t end = end_of_pass(begin);
      judge_pass(begin, end, score);
      begin = end;
    }
    std::stable_sort(
        score.passes.begin(), score.passes.end(),
        [](const MarkingPass& a, const MarkingPass& b) { return a.first_frame < b.first_frame; });
    return score;
  }

 private:
  double time_of(std::size_t row) const { return times_[truth_[rows_[row]].frame]; }
  const VisibleMarking& visible(std::size_t row) const { return truth_[rows_[row]]; }

  // The row after the last of the pass starting at `begin`: the same
  // marking, gaps under kPassGap_s.
  std::size_t end_of_pass(std::size_t begin) const {
    std::size_t end = begin + 1;
    while (end < rows_.size() && visible(end).id == visible(begin).id &&
           time_of(end) - time_of(end - 1) <= kPassGap_s)
      ++end;
    return end;
  }

  void judge_pass(std::size_t begin, std::size_t end, PassScore& score) {
    const VisibleMarking& first = visible(begin);
    const auto found = world_index_.find(first.id);
    if (found == world_index_.end()) return;
    const WorldMarking& marking = world_[found->second];
    const FrameIndex pass_first = first.frame, pass_last = visible(end - 1).frame;
    bool in_range = false;
    for (std::size_t i = begin; i < end; ++i)
      if (in_region(marking, route_[visible(i).frame], region_)) in_range = true;
    const bool cut = pass_first == 0 || odometer_.back() - odometer_[pass_last] < kSettleDistance_m;
    if (in_range && cut) ++score.cut_by_drive_ends;
    if (!in_range || cut) return;

    MarkingPass pass;
    pass.id = first.id;
    pass.label = first.label;
    pass.first_frame = pass_first;
    pass.last_frame = pass_last;
    for (std::size_t i = begin; i < end; ++i)
      if (markings_.paired_label[rows_[i]]) ++pass.detections;
    FrameIndex from = pass_first, to = pass_last;
    while (from > 0 && times_[pass_first] - times_[from - 1] <= kPassMargin_s) --from;
    while (to + 1 < route_.size() && times_[to + 1] - times_[pass_last] <= kPassMargin_s) ++to;
    pass.detections += take_unlisted_detections(marking, begin, end, from, to);
    name_by_landmark(found->second, from, to, pass);
    record(pass, score);
  }

  // Detections within kSameMarking_m of the marking in the frames from..to
  // where visible.csv does not list it, not yet taken.
  std::size_t take_unlisted_detections(const WorldMarking& marking, std::size_t begin, std::size_t end,
                                       FrameIndex from, FrameIndex to) {
    const auto by_frame = [](const DetectionRecord& d, FrameIndex f) { return d.frame < f; };
    std::size_t count = 0;
    std::size_t next_visible = begin;
    for (FrameIndex frame = from; frame <= to; ++frame) {
      while (next_visible < end && visible(next_visible).frame < frame) ++next_visible;
      if (next_visible < end && visible(next_visible).frame == frame) continue;
      const Pose2 seen = in_car_frame(marking, route_[frame]);
      auto d = std::lower_bound(detections_.begin(), detections_.end(), frame, by_frame);
      for (; d != detections_.end() && d->frame == frame; ++d) {
        const auto index = static_cast<std::size_t>(d - detections_.begin());
        if (taken_[index] || std::hypot(d->ground_x - seen.x, d->ground_y - seen.y) > kSameMarking_m)
          continue;
        taken_[index] = true;
        ++count;
      }
    }
    return count;
  }

  // The landmark the ECU made of the marking on this pass: of those on it
  // seen within from..to, the one observed most.
  void name_by_landmark(std::size_t marking, FrameIndex from, FrameIndex to, MarkingPass& pass) const {
    const LandmarkRecord* made = nullptr;
    const auto [on_begin, on_end] = landmarks_on_.equal_range(marking);
    for (auto it = on_begin; it != on_end; ++it) {
      const LandmarkRecord& l = landmarks_[it->second];
      if (l.last_frame < from || l.first_frame > to) continue;
      if (made == nullptr || l.observations > made->observations) made = &l;
    }
    if (made == nullptr) return;
    pass.named = made->label;
    pass.outcome = made->label == pass.label ? PassOutcome::NamedRight : PassOutcome::NamedWrong;
  }

  static void record(const MarkingPass& pass, PassScore& score) {
    score.passes.push_back(pass);
    ++score.outcomes[static_cast<std::size_t>(pass.outcome)];
    if (pass.label < score.passes_of_class.size()) {
      ++score.passes_of_class[pass.label];
      if (pass.outcome == PassOutcome::NamedRight) ++score.named_right_of_class[pass.label];
    }
  }

  const std::vector<WorldMarking>& world_;
  const std::vector<Pose2>& route_;
  const std::vector<double>& times_;
  const std::vector<VisibleMarking>& truth_;
  const std::vector<DetectionRecord>& detections_;
  const MarkingScore& markings_;
  const std::vector<LandmarkRecord>& landmarks_;
  const PassRegion region_;
  std::unordered_map<std::uint32_t, std::size_t> world_index_;
  std::unordered_multimap<std::size_t, std::size_t> landmarks_on_;  // the landmarks on each marking
  std::vector<std::size_t> rows_;
  std::vector<double> odometer_;
  std::vector<bool> taken_;
};

}  // namespace

PassScore score_passes(const std::vector<WorldMarking>& world, const std::vector<Pose2>& route,
                       const std::vector<double>& frame_times, const std::vector<VisibleMarking>& truth,
                       const std::vector<DetectionRecord>& detections, const MarkingScore& markings,
                       const std::vector<LandmarkRecord>& landmarks, const LandmarkScore& placed,
                       const PassRegion& region) {
  if (!pass_inputs_consistent(route, frame_times, truth, detections, markings, landmarks, placed)) return {};
  return PassJudge(world, route, frame_times, truth, detections, markings, landmarks, placed, region)
      .judge_all();
}

double intersection_over_union(const Quad& a, const Quad& b) {
  const auto ha = hull_of(a), hb = hull_of(b);
  const double area_a = cv::contourArea(ha), area_b = cv::contourArea(hb);
  if (!(area_a > 0.0) || !(area_b > 0.0)) return 0.0;
  std::vector<cv::Point2f> overlap;
  const double intersection = cv::intersectConvexConvex(ha, hb, overlap, true);
  if (!(intersection > 0.0)) return 0.0;
  return intersection / (area_a + area_b - intersection);
}

bool centre_inside(const Quad& detection, const Quad& truth) {
  double cx = 0.0, cy = 0.0;
  for (const auto& corner : detection) {
    cx += corner[0] / 4.0;
    cy += corner[1] / 4.0;
  }
  std::vector<cv::Point2f> contour;
  for (const auto& corner : truth)
    contour.emplace_back(static_cast<float>(corner[0]), static_cast<float>(corner[1]));
  return cv::pointPolygonTest(contour, cv::Point2f(static_cast<float>(cx), static_cast<float>(cy)), false) >=
         0.0;
}

MarkingScore score_markings(const std::vector<VisibleMarking>& truth,
                            const std::vector<DetectionRecord>& detections) {
  MarkingScore score;
  score.truth = truth.size();
  score.detections = detections.size();
  score.paired_label.assign(truth.size(), std::nullopt);
  score.detection_paired.assign(detections.size(), false);
  for (const VisibleMarking& t : truth) ++score.per_class[t.label].truth;
  for (const DetectionRecord& d : detections) ++score.per_class[d.label].detections;

  struct Candidate {
    double overlap;  // IoU, plus 1 when the centre is inside: those pair first
    std::size_t detection, truth;
  };
  std::vector<Candidate> candidates;
  std::vector<bool> truth_taken, detection_taken;
  std::size_t t_begin = 0, d_begin = 0;
  while (t_begin < truth.size() || d_begin < detections.size()) {
    // The next frame present in either list.
    FrameIndex frame = ~FrameIndex{0};
    if (t_begin < truth.size()) frame = truth[t_begin].frame;
    if (d_begin < detections.size()) frame = std::min(frame, detections[d_begin].frame);
    std::size_t t_end = t_begin, d_end = d_begin;
    while (t_end < truth.size() && truth[t_end].frame == frame) ++t_end;
    while (d_end < detections.size() && detections[d_end].frame == frame) ++d_end;

    candidates.clear();
    for (std::size_t d = d_begin; d < d_end; ++d) {
      for (std::size_t t = t_begin; t < t_end; ++t) {
        const double iou = intersection_over_union(detections[d].quad, truth[t].quad);
        const bool inside = centre_inside(detections[d].quad, truth[t].quad);
        if (inside || iou >= kMinIntersectionOverUnion)
          candidates.push_back({iou + (inside ? 1.0 : 0.0), d, t});
      }
    }
    std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
      return std::tie(b.overlap, a.detection, a.truth) < std::tie(a.overlap, b.detection, b.truth);
    });
    truth_taken.assign(t_end - t_begin, false);
    detection_taken.assign(d_end - d_begin, false);
    for (const Candidate& c : candidates) {
      if (truth_taken[c.truth - t_begin] || detection_taken[c.detection - d_begin]) continue;
      truth_taken[c.truth - t_begin] = true;
      detection_taken[c.detection - d_begin] = true;
      const Label truth_label = truth[c.truth].label, detected = detections[c.detection].label;
      ++score.matched;
      ++score.per_class[truth_label].truth_found;
      ++score.per_class[detected].detections_matched;
      ++score.confusion[truth_label][detected];
      score.paired_label[c.truth] = detected;
      score.detection_paired[c.detection] = true;
      if (truth_label == detected) {
        ++score.right_label;
        ++score.per_class[truth_label].truth_right_label;
      }
    }
    t_begin = t_end;
    d_begin = d_end;
  }
  return score;
}

}  // namespace markloop::eval
