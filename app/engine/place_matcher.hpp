// Place matching: the landmarks just passed, as a constellation on the
// ground, against the landmarks stored near where the odometry says the car
// is. It needs no order of the markings, so it closes a loop where the car
// turns into an old road, crosses it, or drives it the other way, as soon as
// `MatchConfig::place_landmarks` markings agree.
//
//   newest landmark -> stored landmarks of its label near it (hypotheses)
//     -> each hypothesis predicts where the other recent landmarks lie in the
//        stored map; those found there (same label) are its pairs
//     -> rigid fit of the pairs; odometry prior on the fitted drift; the
//        two visits at most `place_within_m` apart along the drive; labels
//        rare enough (`place_min_bits`)
//     -> a match only when no other place that the odometry could put the
//        car at (a few times the drift limits, within `place_distinct_m`)
//        fits as well: a constellation repeated nearby (the same
//        intersection layout a block away) is never a place.
//     -> a place of two pairs (`place_pair_min_bits`) also needs the cars
//        driving one road at both, and every stored landmark it puts where
//        the car surely looked on its way in seen there again
//        (`place_pair_max_unseen`); one of more pairs whose labels are too
//        common for `place_min_bits`, every such landmark seen again.
#pragma once

#include <array>

#include <Eigen/Core>

#include "app/common/fixed_vector.hpp"
#include "app/engine/config.hpp"
#include "app/engine/rigid_alignment.hpp"
#include "app/engine/sequence_database.hpp"
#include "app/engine/types.hpp"

namespace markloop {

struct MatchEvent;

struct PlaceCounters {
  std::uint64_t queries = 0;
  std::uint64_t hypotheses = 0;  // stored landmarks of the newest one's label nearby
  std::uint64_t too_few_pairs = 0;
  std::uint64_t rejected_residual = 0;
  std::uint64_t rejected_drift = 0;  // beyond the odometry prior
  std::uint64_t ambiguous = 0;       // another alignment fitted as well
  std::uint64_t too_common = 0;      // labels too common to tell the place (place_min_bits)
  std::uint64_t across = 0;          // two pairs, passed by the cars along different roads
  std::uint64_t unseen = 0;          // two pairs, and stored landmarks where the car saw none
  std::uint64_t matches = 0;
};

class PlaceMatcher {
 public:
  static constexpr std::size_t kMaxRecent = 16;

  explicit PlaceMatcher(const MatchConfig& config);

  bool enabled() const { return config_.place_landmarks > 0; }
  // The fewest pairs a place may have.
  unsigned min_pairs() const {
    return config_.place_pair_min_bits > 0.0 ? std::min(2u, config_.place_landmarks)
                                             : config_.place_landmarks;
  }
  // A landmark just released (stored under its id); older ones beyond the
  // window are forgotten.
  void remember(const Landmark& landmark);
  // A remembered landmark's frame, set once the car has passed it
  // (SequenceDatabase::set_frame).
  void set_frame(const Landmark& passed);
  // The id of the newest remembered landmark; kNoLandmark when none.
  LandmarkId newest() const { return recent_.empty() ? kNoLandmark : recent_.back().id; }
  // The car's pose in a frame, at `odometer` metres driven: where it looked.
  void remember_pose(const Pose2& pose, double odometer);
  // The pose was lost: the recent landmarks no longer share a frame.
  void forget() {
    recent_.clear();
    path_size_ = 0;
  }
  // The best place match of the newest remembered landmark: fills `event`'s
  // landmarks, k, alignment, residual and score (not its relative pose).
  bool match(const SequenceDatabase& database, MatchEvent& event);

  const PlaceCounters& counters() const { return counters_; }

 private:
  struct Pair {
    const Landmark* query = nullptr;
    const Landmark* stored = nullptr;
  };
  struct Hypothesis {
    FixedVector<Pair, kMaxSequenceLength> pairs;
    RigidFit fit{};
    double driven_m = 0.0;  // from the newest stored landmark to the newest query
  };

  // Pairs the recent landmarks with stored ones as `anchor` (stored, of the
  // newest's label) predicts, then fits them; false when too few or the fit
  // is poor.
  bool build(const SequenceDatabase& database, const Landmark& anchor, Hypothesis& h);
  // Names each recent landmark's marking: same-label landmarks close enough
  // to be its pieces share one (kPieces_m).
  void group_pieces();
  // Whether a piece of recent_[recent_index]'s marking is paired already.
  bool marking_paired(std::size_t recent_index, const Hypothesis& h) const;
  const Landmark* partner(const SequenceDatabase& database, const Landmark& query, const Eigen::Vector2d& at,
                          double tolerance, const Hypothesis& h) const;
  // Drops the worst fitting pair while that brings the fit within the
  // residual and leaves enough pairs.
  bool fit_pairs(Hypothesis& h) const;
  bool old_enough(const Landmark& stored, const Landmark& query) const;
  // Whether `stored` may be `query`'s marking seen on an earlier visit: old
  // enough, and painted the same way.
  bool could_pair(const Landmark& stored, const Landmark& query) const;
  bool beyond_prior(const Hypothesis& h) const;
  // Mean distance between the paired landmarks: the drift it implies.
  static double apart(const Hypothesis& h);
  // Within a few times the drift limits: it could be where the car is.
  bool plausible(const Hypothesis& h) const;
  // Whether two hypotheses' anchors are different places, not two visits of one.
  bool disagree(const Hypothesis& a, const Hypothesis& b) const;
  void fill(const Hypothesis& h, unsigned verified, MatchEvent& event) const;
  // Sum over the pairs of -log2 of their label's share of the landmarks seen.
  double evidence_bits(const Hypothesis& h) const;
  // The checks a place of two, or one of common labels, must pass besides
  // its bits and its rivals; a refusal is counted.
  bool passes_checks(const SequenceDatabase& database, const Hypothesis& h);
  // Whether at each pair the two cars' headings, aligned, were nearly the
  // same or opposite where they passed it (One), at some pair only a little
  // later (TurnedIn: the car turned into the road there), or not (Across).
  enum class Roads { One, TurnedIn, Across };
  Roads roads(const Hypothesis& h) const;
  // Whether the cars passed the newest pair driving more than a quarter turn
  // apart: the place was met from the other side.
  static bool met_from_opposite(const Hypothesis& h);
  // The car's heading on its recent path a little past `query`, or now.
  double heading_after(const Landmark& query) const;
  // Whether two headings are nearly the same or opposite.
  static bool along_one_road(double yaw_a, double yaw_b);
  // The stored landmarks not paired that `h` puts where the car surely saw
  // a marking on its recent path, since left behind, with no recent
  // landmark of their label there.
  unsigned unseen(const SequenceDatabase& database, const Hypothesis& h) const;
  // Where `p` stands in the car's view on its recent path, driving along the
  // road it was passed on with heading `passed_yaw` (seen from the side, a
  // marking is not surely detected). kPassed: in view over a few metres, and
  // driven far enough since for a marking there to be released; kComing: in
  // view, not yet released.
  enum class View { kOutside, kComing, kPassed };
  View view_of(const Eigen::Vector2d& p, double passed_yaw) const;
  bool seen_recently(Label label, const Eigen::Vector2d& p) const;
  // The box around the car's path within the place window.
  void recent_path_bounds(Eigen::Vector2d& low, Eigen::Vector2d& high) const;
  // Whether `stored` is (a piece of) one of `h`'s paired markings.
  static bool piece_of_pair(const Landmark& stored, const Hypothesis& h);
  // Whether `stored` is another visit's landmark of one of `h`'s paired
  // markings: of its label, as far from it as the odometry can drift
  // between the visits. Aligned onto the visit `h` fits, it lies where that
  // visit's drift put it, not where the marking is.
  bool copy_of_pair(const Landmark& stored, const Hypothesis& h) const;
  // Whether `stored`, of another visit than the one `h` fits, has a copy on
  // that visit (its label, within the drift limits) that `h` puts where the
  // car saw a marking of its label or has not yet released one: the same
  // marking, placed by the other visit's drift. The copy is judged instead.
  bool copy_on_fitted_visit(const SequenceDatabase& database, const Landmark& stored,
                            const Hypothesis& h) const;

  MatchConfig config_;
  FixedVector<Landmark, kMaxRecent> recent_;        // oldest first; the newest last
  std::array<std::uint8_t, kMaxRecent> marking_{};  // per recent landmark (group_pieces)
  static constexpr std::size_t kMaxHypotheses = 16;
  std::array<Hypothesis, kMaxHypotheses> hypotheses_{};
  PlaceCounters counters_;
  // Landmarks seen per label (labels share a bucket beyond 64: a shared
  // bucket only makes its labels look commoner).
  static constexpr std::size_t kLabelBuckets = 64;
  std::array<std::uint64_t, kLabelBuckets> label_counts_{};
  std::uint64_t landmarks_seen_ = 0;
  // The car's recent path, a pose every kPathSpacing_m of driving (a ring).
  struct PathPoint {
    Pose2 pose;
    double odometer = 0.0;
  };
  static constexpr std::size_t kMaxPath = 256;
  std::array<PathPoint, kMaxPath> path_{};
  std::size_t path_next_ = 0;
  std::size_t path_size_ = 0;
  const PathPoint& path_at(std::size_t age) const {  // 0: the newest
    return path_[(path_next_ + kMaxPath - 1 - age) % kMaxPath];
  }
};

}  // namespace markloop
