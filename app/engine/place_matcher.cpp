#include "app/engine/place_matcher.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

#include "app/common/units.hpp"
#include "app/engine/sequence_engine.hpp"

namespace markloop {
namespace {

// Landmarks of one cell examined per lookup (newest first).
constexpr unsigned kPerCell = 32;
// Where a hypothesis expects another recent landmark: within this much, plus
// this share of its distance from the newest one (the drift's rotation is
// not known before the fit).
constexpr double kPredictAbs_m = 0.75;
constexpr double kPredictRel = 0.09;
// Slack on the distance between two earlier visits of one place.
constexpr double kDistinct_m = 2.0;
// A hypothesis this many times beyond the drift limits cannot be where the
// car is, even if the limits were too tight: no rival of one within them.
constexpr double kRivalSlack = 3.0;
// The query's landmarks must spread at least this far: side by side markings
// of one row leave the rotation unknown.
constexpr double kMinSpread_m = 3.0;
// Landmarks of one label closer than this (or joined by a chain of such)
// may be pieces of one marking (a crosswalk's stripes detected in groups):
// pieces in a row fit any other such row shifted along it, so one marking
// is paired once.
constexpr double kPieces_m = 3.0;
// The car's path is kept a pose every this much driving (kMaxPath of them:
// more than the place window and the view's depth).
constexpr double kPathSpacing_m = 0.5;
// A marking is surely detected when in view over this much driving, and
// released once the car is this far past the view's near edge.
constexpr double kLookedAt_m = 3.0;
constexpr double kReleasedPast_m = 6.0;
// A stored landmark is seen again by a recent landmark of its label within
// this much of where the place puts it.
constexpr double kSeenWithin_m = 1.5;
// At each pair of a place of two the cars drove along one road, one way or
// the other: headings this close to the same or the opposite (met from a
// cross street, one intersection's markings are seen from elsewhere). A
// stored marking is looked for only from along the road it was passed on.
constexpr double kAlongRoad_deg = 30.0;
// A place of two, or of common labels, fits this well (RMS): two pairs fit
// any two markings whose distances agree, and a look-alike rarely to within
// a decimetre.
constexpr double kCheckedMaxResidual_m = 0.1;
// A car turning into the road passes its first markings mid-turn: its
// heading this far past them shows the road it turned into.
constexpr double kTurnedIn_m = 10.0;

Eigen::Vector2d point(const Landmark& l) {
  return {l.x, l.y};
}

// Whether two landmarks of one label could be one marking by the way it is
// painted: markings facing opposite ways on the ground are two (cars on
// parallel streets each read their own lane's arrow or bike). A place turns
// one visit by no more than the drift limits, far less than a quarter turn.
bool facings_agree(const Landmark& a, const Landmark& b) {
  const std::optional<double> yaw_a = facing_yaw(a), yaw_b = facing_yaw(b);
  return !yaw_a || !yaw_b || std::cos(*yaw_a - *yaw_b) > 0.0;
}

// `p` moved by the rigid transform `t`.
Eigen::Vector2d moved(const Pose2& t, const Eigen::Vector2d& p) {
  const Pose2 q = compose(t, {p.x(), p.y(), 0.0});
  return {q.x, q.y};
}

}  // namespace

PlaceMatcher::PlaceMatcher(const MatchConfig& config) : config_(config) {}

void PlaceMatcher::remember(const Landmark& landmark) {
  while (!recent_.empty() && recent_[0].station < landmark.station - config_.place_window_m)
    recent_.erase_at(0);
  if (recent_.full()) recent_.erase_at(0);
  (void)recent_.push_back(landmark);
  ++label_counts_[landmark.label % kLabelBuckets];
  ++landmarks_seen_;
}

void PlaceMatcher::set_frame(const Landmark& passed) {
  for (Landmark& l : recent_)
    if (l.id == passed.id) copy_frame(passed, l);
}

double PlaceMatcher::evidence_bits(const Hypothesis& h) const {
  // How rarely the paired labels occur among the landmarks seen so far: two
  // crosswalks and a stop line, at every intersection, say little; a speed
  // number beside them says more.
  double bits = 0.0;
  for (const Pair& p : h.pairs) {
    const double count = static_cast<double>(label_counts_[p.query->label % kLabelBuckets]);
    bits += std::log2((static_cast<double>(landmarks_seen_) + 1.0) / (count + 1.0));
  }
  return bits;
}

void PlaceMatcher::remember_pose(const Pose2& pose, double odometer) {
  if (path_size_ > 0 && odometer < path_at(0).odometer + kPathSpacing_m) return;
  path_[path_next_] = {pose, odometer};
  path_next_ = (path_next_ + 1) % kMaxPath;
  path_size_ = std::min(path_size_ + 1, kMaxPath);
}

bool PlaceMatcher::old_enough(const Landmark& stored, const Landmark& query) const {
  // A loaded map's landmarks (negative stations) lie in another world frame.
  return stored.station >= 0.0 && stored.has_car_pose &&
         stored.station <= query.station - config_.min_separation_m &&
         stored.t <= query.t - config_.min_separation_s;
}

bool PlaceMatcher::could_pair(const Landmark& stored, const Landmark& query) const {
  return old_enough(stored, query) && facings_agree(stored, query);
}

bool PlaceMatcher::match(const SequenceDatabase& database, MatchEvent& event) {
  if (!enabled() || recent_.empty()) return false;
  const Landmark& newest = recent_.back();
  if (!newest.has_car_pose || recent_.size() < min_pairs()) return false;
  ++counters_.queries;
  group_pieces();
  std::size_t found = 0;
  bool overflow = false;
  database.for_each_landmark_near(newest.label, newest.x, newest.y,
                                  std::max(config_.place_distinct_m, config_.place_search_m), kPerCell,
                                  [&](const Landmark& anchor) {
                                    if (!could_pair(anchor, newest)) return;
                                    ++counters_.hypotheses;
                                    if (found == kMaxHypotheses) {
                                      overflow = true;
                                      return;
                                    }
                                    if (build(database, anchor, hypotheses_[found])) ++found;
                                  });
  // Too many look-alikes to tell them apart: no place.
  if (overflow) {
    ++counters_.ambiguous;
    return false;
  }
  // The best hypothesis within the odometry prior...
  std::size_t best = found;
  for (std::size_t i = 0; i < found; ++i) {
    if (beyond_prior(hypotheses_[i])) {
      ++counters_.rejected_drift;
      continue;
    }
    const Hypothesis& h = hypotheses_[i];
    if (best == found || h.pairs.size() > hypotheses_[best].pairs.size() ||
        (h.pairs.size() == hypotheses_[best].pairs.size() &&
         h.fit.rms_residual < hypotheses_[best].fit.rms_residual))
      best = i;
  }
  if (best == found) return false;
  // A place of two, or of more markings whose labels say too little (an
  // intersection's crosswalks and stop line), is judged by the checks that
  // make two pairs enough.
  const double bits = evidence_bits(hypotheses_[best]);
  const bool checked = hypotheses_[best].pairs.size() < config_.place_landmarks ||
                       (config_.place_pair_min_bits > 0.0 && bits < config_.place_min_bits);
  if (bits < (checked ? config_.place_pair_min_bits : config_.place_min_bits)) {
    ++counters_.too_common;
    return false;
  }
  if (checked && !passes_checks(database, hypotheses_[best])) return false;
  // ...with no plausible rival: another visit of the same place agrees. A
  // checked place has rivals of two pairs too.
  for (std::size_t i = 0; i < found; ++i) {
    if (!checked && hypotheses_[i].pairs.size() < config_.place_landmarks) continue;
    if (plausible(hypotheses_[i]) && disagree(hypotheses_[i], hypotheses_[best])) {
      ++counters_.ambiguous;
      return false;
    }
  }
  ++counters_.matches;
  fill(hypotheses_[best], static_cast<unsigned>(found), event);
  return true;
}

bool PlaceMatcher::passes_checks(const SequenceDatabase& database, const Hypothesis& h) {
  if (h.fit.rms_residual > kCheckedMaxResidual_m) {
    ++counters_.rejected_residual;
    return false;
  }
  if (met_from_opposite(h) && h.driven_m > config_.place_opposite_within_m) {
    ++counters_.rejected_drift;
    return false;
  }
  unsigned max_unseen = config_.place_pair_max_unseen;
  if (h.pairs.size() == 2) {
    const Roads on = roads(h);
    if (on == Roads::Across) {
      ++counters_.across;
      return false;
    }
    // A car passing a marking mid-turn could have passed another of the
    // intersection's: nothing may go unseen.
    if (on == Roads::TurnedIn) max_unseen = 0;
  } else {
    // Three pairs fix the alignment wherever the cars drove (both may have
    // turned at the intersection), but their labels say little: nothing may
    // go unseen.
    max_unseen = 0;
  }
  if (unseen(database, h) > max_unseen) {
    ++counters_.unseen;
    return false;
  }
  return true;
}

bool PlaceMatcher::build(const SequenceDatabase& database, const Landmark& anchor, Hypothesis& h) {
  const Landmark& newest = recent_.back();
  h.pairs.clear();
  (void)h.pairs.push_back({&newest, &anchor});
  const Eigen::Vector2d shift = point(anchor) - point(newest);
  // Newest first: the landmarks nearest the anchor are predicted best.
  for (std::size_t i = recent_.size() - 1; i-- > 0 && !h.pairs.full();) {
    const Landmark& q = recent_[i];
    if (marking_paired(i, h)) continue;
    const double reach = (point(q) - point(newest)).norm();
    const Landmark* stored = partner(database, q, point(q) + shift, kPredictAbs_m + kPredictRel * reach, h);
    if (stored != nullptr) (void)h.pairs.push_back({&q, stored});
  }
  if (h.pairs.size() < min_pairs()) {
    ++counters_.too_few_pairs;
    return false;
  }
  if (!fit_pairs(h)) {
    ++counters_.rejected_residual;
    return false;
  }
  double newest_stored = 0.0;
  for (const Pair& p : h.pairs) newest_stored = std::max(newest_stored, p.stored->station);
  h.driven_m = newest.station - newest_stored;
  return true;
}

void PlaceMatcher::group_pieces() {
  // Union of same-label landmarks within kPieces_m: the smallest index of
  // each chain names it (few landmarks: a few hundred comparisons).
  for (std::size_t i = 0; i < recent_.size(); ++i) marking_[i] = static_cast<std::uint8_t>(i);
  for (bool changed = true; changed;) {
    changed = false;
    for (std::size_t i = 0; i < recent_.size(); ++i)
      for (std::size_t j = i + 1; j < recent_.size(); ++j) {
        if (recent_[i].label != recent_[j].label || marking_[i] == marking_[j] ||
            (point(recent_[i]) - point(recent_[j])).squaredNorm() >= kPieces_m * kPieces_m)
          continue;
        marking_[i] = marking_[j] = std::min(marking_[i], marking_[j]);
        changed = true;
      }
  }
}

bool PlaceMatcher::marking_paired(std::size_t recent_index, const Hypothesis& h) const {
  for (const Pair& p : h.pairs)
    if (marking_[static_cast<std::size_t>(p.query - recent_.begin())] == marking_[recent_index]) return true;
  return false;
}

const Landmark* PlaceMatcher::partner(const SequenceDatabase& database, const Landmark& query,
                                      const Eigen::Vector2d& at, double tolerance,
                                      const Hypothesis& h) const {
  const Landmark* best = nullptr;
  double best_sq = 0.0;
  database.for_each_landmark_near(query.label, at.x(), at.y(), tolerance, kPerCell, [&](const Landmark& s) {
    if (!could_pair(s, query)) return;
    for (const Pair& p : h.pairs)
      if (p.stored->id == s.id) return;
    const double d_sq = (point(s) - at).squaredNorm();
    if (best == nullptr || d_sq < best_sq) {
      best = &s;
      best_sq = d_sq;
    }
  });
  return best;
}

bool PlaceMatcher::fit_pairs(Hypothesis& h) const {
  std::array<Eigen::Vector2d, kMaxSequenceLength> from{}, to{};
  for (;;) {
    const std::size_t n = h.pairs.size();
    double spread_sq = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      from[i] = point(*h.pairs[i].stored);
      to[i] = point(*h.pairs[i].query);
      spread_sq = std::max(spread_sq, (to[i] - to[0]).squaredNorm());
    }
    if (spread_sq < kMinSpread_m * kMinSpread_m) return false;
    h.fit = fit_rigid_2d({from.data(), n}, {to.data(), n});
    if (h.fit.rms_residual <= std::min(config_.max_residual_m, config_.place_max_residual_m)) return true;
    if (n <= min_pairs()) return false;
    // The worst pair goes, never the newest (pair 0): it is the hypothesis.
    const double c = std::cos(h.fit.transform.yaw), s = std::sin(h.fit.transform.yaw);
    std::size_t worst = 1;
    double worst_sq = -1.0;
    for (std::size_t i = 1; i < n; ++i) {
      const Eigen::Vector2d mapped(h.fit.transform.x + c * from[i].x() - s * from[i].y(),
                                   h.fit.transform.y + s * from[i].x() + c * from[i].y());
      const double e = (mapped - to[i]).squaredNorm();
      if (e > worst_sq) worst = i, worst_sq = e;
    }
    h.pairs.erase_at(worst);
  }
}

double PlaceMatcher::apart(const Hypothesis& h) {
  Eigen::Vector2d query_centre = Eigen::Vector2d::Zero(), stored_centre = Eigen::Vector2d::Zero();
  for (const Pair& p : h.pairs) {
    query_centre += point(*p.query);
    stored_centre += point(*p.stored);
  }
  return (query_centre - stored_centre).norm() / static_cast<double>(h.pairs.size());
}

bool PlaceMatcher::plausible(const Hypothesis& h) const {
  return apart(h) <= kRivalSlack * drift_allowed_m(config_, h.driven_m);
}

bool PlaceMatcher::beyond_prior(const Hypothesis& h) const {
  const double allowed = std::min(config_.place_search_m, drift_allowed_m(config_, h.driven_m));
  const double turned = std::abs(h.fit.transform.yaw) * kDegreesPerRadian;
  return h.driven_m > config_.place_within_m || apart(h) > allowed ||
         turned > drift_allowed_deg(config_, h.driven_m);
}

bool PlaceMatcher::disagree(const Hypothesis& a, const Hypothesis& b) const {
  // Two earlier visits of one place lie as far apart as the odometry drifted
  // between them; two anchors of one visit are one place only when they are
  // one marking. Anything else is a look-alike (another crosswalk of the
  // same intersection, the same layout a block away).
  const Landmark& anchor_a = *a.pairs[0].stored;
  const Landmark& anchor_b = *b.pairs[0].stored;
  const double driven = std::abs(anchor_a.station - anchor_b.station);
  const double drifted = driven <= config_.place_window_m
                             ? 0.0
                             : std::min(config_.place_search_m, drift_allowed_m(config_, driven));
  return (point(anchor_a) - point(anchor_b)).norm() > drifted + kDistinct_m;
}

PlaceMatcher::Roads PlaceMatcher::roads(const Hypothesis& h) const {
  Roads roads = Roads::One;
  for (const Pair& p : h.pairs) {
    if (!p.query->has_car_pose || !p.stored->has_car_pose) return Roads::Across;
    const double stored_yaw = p.stored->car_yaw + h.fit.transform.yaw;
    if (along_one_road(p.query->car_yaw, stored_yaw)) continue;
    if (!along_one_road(heading_after(*p.query), stored_yaw)) return Roads::Across;
    roads = Roads::TurnedIn;
  }
  return roads;
}

bool PlaceMatcher::met_from_opposite(const Hypothesis& h) {
  const Pair& newest = h.pairs[0];
  if (!newest.query->has_car_pose || !newest.stored->has_car_pose) return false;
  const double stored_yaw = newest.stored->car_yaw + h.fit.transform.yaw;
  return std::cos(wrap_angle(newest.query->car_yaw - stored_yaw)) < 0.0;
}

double PlaceMatcher::heading_after(const Landmark& query) const {
  // The newest pose at most kTurnedIn_m past the landmark.
  if (path_size_ == 0) return query.car_yaw;
  const double at = query.station + kTurnedIn_m;
  std::size_t age = 0;
  while (age + 1 < path_size_ && path_at(age).odometer > at) ++age;
  return path_at(age).pose.yaw;
}

bool PlaceMatcher::along_one_road(double yaw_a, double yaw_b) {
  const double turned = std::abs(wrap_angle(yaw_a - yaw_b)) * kDegreesPerRadian;
  return turned <= kAlongRoad_deg || turned >= 180.0 - kAlongRoad_deg;
}

unsigned PlaceMatcher::unseen(const SequenceDatabase& database, const Hypothesis& h) const {
  if (path_size_ == 0) return 0;
  // The stored landmarks within view of the recent path, aligned onto it
  // (labels beyond the buckets are not looked for).
  Eigen::Vector2d low, high;
  recent_path_bounds(low, high);
  const Eigen::Vector2d centre = moved(inverse(h.fit.transform), 0.5 * (low + high));
  const double reach =
      0.5 * (high - low).norm() +
      std::hypot(config_.place_view_near_m + config_.place_view_depth_m, config_.place_view_side_m);
  const Landmark& newest = recent_.back();
  unsigned count = 0;
  for (std::size_t bucket = 0; bucket < kLabelBuckets; ++bucket) {
    if (label_counts_[bucket] == 0) continue;
    database.for_each_landmark_near(
        static_cast<Label>(bucket), centre.x(), centre.y(), reach, kPerCell, [&](const Landmark& stored) {
          if (!old_enough(stored, newest) || piece_of_pair(stored, h) || copy_of_pair(stored, h)) return;
          const Eigen::Vector2d p = moved(h.fit.transform, point(stored));
          const double passed_yaw = stored.car_yaw + h.fit.transform.yaw;
          if (view_of(p, passed_yaw) == View::kPassed && !seen_recently(stored.label, p) &&
              !copy_on_fitted_visit(database, stored, h))
            ++count;
        });
  }
  return count;
}

void PlaceMatcher::recent_path_bounds(Eigen::Vector2d& low, Eigen::Vector2d& high) const {
  const double window_start = path_at(0).odometer - config_.place_window_m;
  low = high = {path_at(0).pose.x, path_at(0).pose.y};
  for (std::size_t age = 0; age < path_size_ && path_at(age).odometer >= window_start; ++age) {
    const Eigen::Vector2d p(path_at(age).pose.x, path_at(age).pose.y);
    low = low.cwiseMin(p), high = high.cwiseMax(p);
  }
}

bool PlaceMatcher::piece_of_pair(const Landmark& stored, const Hypothesis& h) {
  for (const Pair& pair : h.pairs)
    if (stored.label == pair.stored->label && (point(stored) - point(*pair.stored)).norm() < kPieces_m)
      return true;
  return false;
}

bool PlaceMatcher::copy_of_pair(const Landmark& stored, const Hypothesis& h) const {
  for (const Pair& pair : h.pairs) {
    const double driven_between = std::abs(stored.station - pair.stored->station);
    if (stored.label == pair.stored->label && driven_between > config_.place_window_m &&
        (point(stored) - point(*pair.stored)).norm() <= drift_allowed_m(config_, driven_between))
      return true;
  }
  return false;
}

bool PlaceMatcher::copy_on_fitted_visit(const SequenceDatabase& database, const Landmark& stored,
                                        const Hypothesis& h) const {
  const auto on_fitted_visit = [&](const Landmark& l) {
    for (const Pair& pair : h.pairs)
      if (std::abs(l.station - pair.stored->station) <= config_.place_window_m) return true;
    return false;
  };
  if (on_fitted_visit(stored)) return false;
  const double driven_between = std::abs(stored.station - h.pairs[0].stored->station);
  const double reach = std::min(config_.place_search_m, drift_allowed_m(config_, driven_between));
  bool found = false;
  database.for_each_landmark_near(
      stored.label, stored.x, stored.y, reach, kPerCell, [&](const Landmark& copy) {
        if (found || !on_fitted_visit(copy)) return;
        const Eigen::Vector2d p = moved(h.fit.transform, point(copy));
        found =
            seen_recently(copy.label, p) || view_of(p, copy.car_yaw + h.fit.transform.yaw) == View::kComing;
      });
  return found;
}

PlaceMatcher::View PlaceMatcher::view_of(const Eigen::Vector2d& p, double passed_yaw) const {
  const double now = path_at(0).odometer;
  const double window_start = now - config_.place_window_m;
  bool in_view = false;
  double first = 0.0, last = 0.0;  // odometer, in view
  for (std::size_t age = 0; age < path_size_ && path_at(age).odometer >= window_start; ++age) {
    const PathPoint& at = path_at(age);
    if (!along_one_road(at.pose.yaw, passed_yaw)) continue;
    const double dx = p.x() - at.pose.x, dy = p.y() - at.pose.y;
    const double ahead = std::cos(at.pose.yaw) * dx + std::sin(at.pose.yaw) * dy;
    const double left = -std::sin(at.pose.yaw) * dx + std::cos(at.pose.yaw) * dy;
    if (ahead < config_.place_view_near_m || ahead > config_.place_view_near_m + config_.place_view_depth_m ||
        std::abs(left) > config_.place_view_side_m)
      continue;
    if (!in_view) last = at.odometer;
    in_view = true;
    first = at.odometer;
  }
  if (!in_view) return View::kOutside;
  if (now - last < config_.place_view_near_m + kReleasedPast_m) return View::kComing;
  return last - first >= kLookedAt_m ? View::kPassed : View::kOutside;
}

bool PlaceMatcher::seen_recently(Label label, const Eigen::Vector2d& p) const {
  for (const Landmark& l : recent_)
    if (l.label == label && (point(l) - p).norm() <= kSeenWithin_m) return true;
  return false;
}

void PlaceMatcher::fill(const Hypothesis& h, unsigned verified, MatchEvent& event) const {
  // Oldest query landmark first, as a sequence's. The loop names the frames
  // of the pair whose cars were closest (SequenceEngine::framed_pair).
  std::array<Pair, kMaxSequenceLength> ordered{};
  const std::size_t n = h.pairs.size();
  std::copy(h.pairs.begin(), h.pairs.end(), ordered.begin());
  std::sort(ordered.begin(), ordered.begin() + static_cast<std::ptrdiff_t>(n),
            [](const Pair& a, const Pair& b) { return a.query->station < b.query->station; });
  event = MatchEvent{};
  event.k = static_cast<unsigned>(n);
  for (std::size_t i = 0; i < n; ++i) {
    event.query[i] = *ordered[i].query;
    event.match[i] = *ordered[i].stored;
  }
  event.alignment = h.fit.transform;
  event.residual_m = h.fit.rms_residual;
  event.aligned_pairs = event.k;
  event.score = std::clamp(1.0 - h.fit.rms_residual / config_.max_residual_m, 0.0, 1.0);
  event.verified_candidates = verified;
}

}  // namespace markloop
