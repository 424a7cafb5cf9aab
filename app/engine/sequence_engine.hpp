// The online road-marking sequence engine: observations in, matches out.
//
//   observations -> LandmarkTracker -> (release in along-track order)
//     -> rows of side-by-side landmarks -> every chain of k rows ending at
//        the new landmark (and of k of the last k + 1, one row stepped over)
//     -> query the database -> verify by rigid alignment
//        -> MatchEvent; then the new sequences are stored.
//
// All memory is allocated in the constructor; process_frame() does not touch
// the heap.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>

#include "app/common/fixed_vector.hpp"
#include "app/engine/config.hpp"
#include "app/engine/landmark_tracker.hpp"
#include "app/engine/place_matcher.hpp"
#include "app/engine/rigid_alignment.hpp"
#include "app/engine/sequence_database.hpp"
#include "app/engine/types.hpp"

#include <Eigen/Core>

namespace markloop {

struct MatchEvent {
  unsigned k = 0;
  std::array<Landmark, kMaxSequenceLength> query{};  // the new sequence
  std::array<Landmark, kMaxSequenceLength> match{};  // the stored place it matched
  // Rigid transform taking the matched landmarks' world positions onto the
  // query's: the drift accumulated between the two visits.
  Pose2 alignment{};
  // The pair whose two frames the loop names: a sequence's newest, unless
  // they lie beyond the frames-apart limit; then, and for a place, the pair
  // whose cars lay closest (SequenceEngine::framed_pair).
  unsigned framed = 0;
  // The car's pose in the query's framed frame, expressed in the car's frame
  // in the match's, after correcting by `alignment`: the loop closure
  // constraint a pose graph needs. Only when both poses are known.
  bool has_relative_pose = false;
  Pose2 relative_pose{};
  double residual_m = 0.0;  // RMS of the aligned landmark positions
  // Landmark pairs behind `alignment`: k, or more when this match continues
  // the previous one (the same closure, a row further on).
  unsigned aligned_pairs = 0;
  double score = 0.0;  // 1 = distances agree exactly, 0 = at tolerance
  unsigned verified_candidates = 0;

  FrameIndex query_frame() const { return query[framed].last_frame; }
  FrameIndex match_frame() const { return match[framed].last_frame; }
};

class MatchSink {
 public:
  virtual void on_match(const MatchEvent& event) = 0;

 protected:
  ~MatchSink() = default;
};

struct EngineCounters {
  std::uint64_t frames = 0;
  std::uint64_t frames_out_of_order = 0;
  std::uint64_t observations_over_limit = 0;
  std::uint64_t landmarks_released = 0;
  // No frame remembered near a landmark's station (a crawl filled the
  // history): the oldest one represents it.
  std::uint64_t passing_frames_forgotten = 0;
  // Flushed before the car reached them: stored for later visits, not
  // queried, since no frame shows the car at them.
  std::uint64_t landmarks_flushed_ahead = 0;
  std::uint64_t landmarks_unchained = 0;  // row already full
  std::uint64_t pending_overflows = 0;
  std::uint64_t chain_breaks = 0;
  std::uint64_t sequences_created = 0;
  std::uint64_t sequences_capped = 0;            // chains beyond the per-landmark cap
  std::uint64_t sequences_over_skipped_row = 0;  // of sequences_created, stepping over a row
  std::uint64_t queries = 0;
  std::uint64_t candidates = 0;  // labels and distances agree
  std::uint64_t candidates_too_recent = 0;
  std::uint64_t candidates_rejected_residual = 0;
  std::uint64_t candidates_rejected_drift = 0;  // beyond the odometry prior
  // The same markings, but the two frames apart (max_frame_distance_m).
  std::uint64_t candidates_rejected_frames_apart = 0;
  std::uint64_t loaded_single_sequences = 0;  // into a loaded map, not yet over k + 1 rows
  std::uint64_t loaded_hypotheses = 0;        // first matches into a loaded map, held back
  std::uint64_t loaded_hypotheses_sent = 0;   // ... and sent once a later match confirmed them
  std::uint64_t loaded_rivalled = 0;          // not confirmed: a rival alignment as well supported
  std::uint64_t loaded_rejected = 0;          // disagreeing with the confirmed alignment
  std::uint64_t candidate_limit_hits = 0;
  std::uint64_t matches = 0;
  std::uint64_t closures_extended = 0;  // alignment fitted on a run of matches
  // Of matches, found by a query stepping over a row (a plain query that meets
  // a stored sequence over a skipped row is not counted here).
  std::uint64_t matches_over_skipped_row = 0;
  std::uint64_t place_matches = 0;  // of matches, by place (PlaceMatcher)
  // Sequence matches between visits far apart, held until further rows continue them.
  std::uint64_t matches_held_far = 0;
};

class SequenceEngine {
 public:
  static constexpr std::size_t kMaxObservationsPerFrame = 32;
  static constexpr std::size_t kMaxPending = 128;
  static constexpr std::size_t kMaxRowSize = 4;
  static constexpr unsigned kMaxSequencesPerLandmark = 64;

  // Precondition: validate(config) == nullptr.
  explicit SequenceEngine(const EngineConfig& config);

  // Feeds one frame. Observations beyond kMaxObservationsPerFrame are dropped
  // and counted by the tracker.
  void process_frame(const FrameInput& frame, std::span<const Observation> observations, MatchSink& sink);
  // End of a drive: commits and releases everything still in flight.
  void flush(MatchSink& sink);
  // The pose is unknown for a while: landmarks in flight are released and no
  // sequence may span the gap.
  void break_chains(MatchSink& sink);

  const EngineConfig& config() const { return config_; }
  const EngineCounters& counters() const { return counters_; }
  const TrackerCounters& tracker_counters() const { return tracker_.counters(); }
  const PlaceCounters& place_counters() const { return places_.counters(); }
  const OdometryScaleEstimator& odometry_scale() const { return tracker_.odometry_scale(); }
  const SequenceDatabase& database() const { return database_; }
  // Between frames only: loading a saved map at start-up, clearing on command.
  SequenceDatabase& mutable_database() { return database_; }
  double odometer() const { return odometer_; }

 private:
  struct Row {
    double anchor_station = 0.0;
    FixedVector<LandmarkId, kMaxRowSize> members;
  };

  void commit_and_release(double now, bool all, MatchSink& sink);
  void remember_frame(const FrameInput& frame);
  // Makes the frame in which the car came closest to the landmark so far the
  // one that represents it; false if the car has not reached it yet.
  bool represent_by_passing_frame(Landmark& landmark);
  // Landmarks released before the car reached them get their frame of
  // closest approach once it has passed them.
  void represent_passed_landmarks(MatchSink& sink);
  // `flushing`: released by flush() or break_chains(), not in order.
  void release(Landmark landmark, bool flushing, MatchSink& sink);
  // Stores the sequences ending at `id`; looks for their matches first when
  // `may_match`. True when one matched.
  bool chain(LandmarkId id, bool may_match, MatchSink& sink);
  // The newest landmark's place, when no sequence matched it.
  enum class PlaceOutcome { kNone, kSent, kFramesApart };
  PlaceOutcome match_place(MatchSink& sink);
  // Best verified match of one new sequence (`over_skipped_row`: it steps
  // over one of the earlier rows); false when there is none. Each candidate
  // the database proposes goes through verify_candidate(); keep_if_best()
  // keeps the one that fits best.
  bool match(std::span<const LandmarkId> query, const SequenceShape& shape, bool over_skipped_row,
             MatchEvent& best);
  // Which pair's frames a loop names: a sequence's newest, unless they lie
  // too far apart; a place's whose cars were closest (an intersection
  // approached from two directions: the cars pass one crosswalk a street's
  // width apart, another side by side).
  enum class Framing { kNewest, kClosestCars };
  void set_relative_pose(MatchEvent& event, Framing framing = Framing::kNewest) const;
  unsigned framed_pair(const MatchEvent& event, Framing framing) const;
  // How far apart the two cars lie, aligned; none without their poses.
  static std::optional<double> frames_apart(const Pose2& alignment, const Landmark& query,
                                            const Landmark& match);
  // When `event` continues the previous closure (its sequences overlap the
  // previous ones but for one row), refits its alignment on every pair of the
  // run: k points nearly in a line along the road leave the rotation, and so
  // the pose at the car, the least certain; a few more rows pin it down.
  void extend_closure_run(MatchEvent& event);
  // A match between visits more than far_after_m apart whose run still
  // spans less than far_run_m.
  bool waits_for_longer_run(const MatchEvent& event) const;

  // The new sequence being matched; its landmarks live in the MatchEvent
  // being filled.
  struct Query {
    std::span<const LandmarkId> ids;
    const SequenceShape* shape = nullptr;
    bool over_skipped_row = false;
    const Landmark* landmarks = nullptr;  // k of them, oldest first
    std::array<Eigen::Vector2d, kMaxSequenceLength> points{};
    const Landmark& first() const { return landmarks[0]; }
    const Landmark& last() const { return landmarks[ids.size() - 1]; }
  };
  // A stored sequence whose labels and distances agree with the query's.
  struct Candidate {
    std::span<const LandmarkId> ids;
    std::array<Eigen::Vector2d, kMaxSequenceLength> points{};
    double normalised_error = 0.0;  // distance errors in tolerances, summed
    RigidFit fit{};                 // candidate onto query
  };
  Query load_query(std::span<const LandmarkId> ids, const SequenceShape& shape, bool over_skipped_row,
                   MatchEvent& best) const;
  // The steps a candidate must pass, in order, each counting its rejections:
  // far enough back, rigid fit within the residual, frames close enough,
  // then the loaded map's confirmation or the odometry prior.
  bool verify_candidate(const Query& query, std::span<const LandmarkId> ids, Candidate& candidate);
  // Too close behind the query (in distance or time) to be an earlier visit.
  bool too_recent(const Query& query, std::span<const LandmarkId> ids) const;
  // Fills the candidate's points and its distance error.
  void measure_candidate(const Query& query, std::span<const LandmarkId> ids, Candidate& candidate) const;
  bool frames_too_far_apart(const Query& query, const Candidate& candidate) const;
  // A loop's two frames further apart than max_frame_distance_m by its
  // relative pose (none: unknown, not too far).
  bool frames_too_far_apart(const std::optional<double>& apart_m) const;
  // A candidate in a loaded map (no odometry prior): true once it continues
  // a verified sequence and its alignment is confirmed.
  bool accept_into_loaded_map(const Query& query, const Candidate& candidate);
  // Whether the sequence a row back matched this candidate's a row back;
  // remembers this pair for the next one.
  bool continues_loaded_sequence(const Query& query, const Candidate& candidate);
  struct SessionAlignment;
  SessionAlignment proposed_alignment(const Query& query, const Candidate& candidate) const;
  bool agrees_with_confirmed(const SessionAlignment& proposed);
  // No alignment confirmed yet: confirms this one, or holds it back as a
  // hypothesis (false).
  bool confirm_by_hypotheses(const Query& query, const Candidate& candidate,
                             const SessionAlignment& proposed);
  bool supports(const SessionAlignment& hypothesis, const SessionAlignment& proposed) const;
  // Support of the best supported hypothesis that `proposed` disagrees with.
  unsigned strongest_rival_support(const SessionAlignment& proposed) const;
  void hold_hypothesis(const Query& query, const Candidate& candidate, const SessionAlignment& proposed);
  // Same session: the places differ by more than the odometry can drift.
  bool beyond_odometry_prior(const Query& query, const Candidate& candidate) const;
  // 1 = distances agree exactly, 0 = at tolerance.
  double score_of(const Candidate& candidate) const;
  void keep_if_best(const Candidate& candidate, bool& found, MatchEvent& best) const;

  EngineConfig config_;
  LandmarkTracker tracker_;
  SequenceDatabase database_;
  PlaceMatcher places_;
  EngineCounters counters_;

  double odometer_ = 0.0;
  bool have_previous_pose_ = false;
  Pose2 previous_pose_{};
  double last_t_ = 0.0;

  FixedVector<Landmark, kMaxPending> committed_;   // scratch for the tracker
  FixedVector<Landmark, kMaxPending> pending_;     // sorted by station
  FixedVector<LandmarkId, kMaxPending> unpassed_;  // released ahead of the car
  // The newest landmark, released ahead of the car, whose place was refused
  // for frames apart; kNoLandmark when none.
  LandmarkId place_retry_ = kNoLandmark;
  bool have_released_ = false;
  Landmark last_released_{};

  // The car's recent frames, one every `history_spacing_m_` of driving, so
  // that a released landmark can be represented by the frame in which the car
  // came closest to it: the same spot on every visit, whatever the detection
  // range.
  struct PassingFrame {
    FrameIndex frame = 0;
    double t = 0.0;
    double odometer = 0.0;
    Pose2 pose{};
  };
  static constexpr std::size_t kFrameHistory = 1024;
  // The closest approach is looked for this far either side of the station.
  static constexpr double kPassingWindow_m = 10.0;
  // A landmark released ahead of the car is given its frame of closest
  // approach once the car is this far past its station.
  static constexpr double kPassedBy_m = 2.0;
  std::array<PassingFrame, kFrameHistory> history_{};
  std::size_t history_oldest_ = 0;
  std::size_t history_size_ = 0;
  double history_spacing_m_ = 0.0;
  const PassingFrame& history_at(std::size_t i) const {
    return history_[(history_oldest_ + i) % kFrameHistory];
  }

  // Landmark pairs of the current run of matches continuing each other.
  struct LandmarkPair {
    LandmarkId query = kNoLandmark;
    LandmarkId match = kNoLandmark;
    bool operator==(const LandmarkPair&) const = default;
  };
  static constexpr std::size_t kMaxRunPairs = 6;
  FixedVector<LandmarkPair, kMaxRunPairs> closure_run_;
  double closure_run_start_station_ = 0.0;  // of the run's first query landmark
  // Last landmarks of recent verified sequences into a loaded map, so that a
  // sequence a row further on can be seen to continue one.
  FixedVector<LandmarkPair, 32> loaded_pairs_;

  // The last k rows (k + 1 when a row may be skipped), oldest first.
  FixedVector<Row, kMaxSequenceLength + 1> rows_;
  MatchEvent best_;  // scratch, kept here to keep the stack small

  // How a loaded map's world frame relates to this session's (see
  // MatchConfig::confirm_loaded_places): a hypothesis, then confirmed.
  struct SessionAlignment {
    bool valid = false;
    Pose2 transform{};     // loaded world -> this session's world
    double station = 0.0;  // where it was last supported
    // The matched places' centres, loaded and this session's (for rivals).
    Eigen::Vector2d from = Eigen::Vector2d::Zero(), to = Eigen::Vector2d::Zero();
  };
  static constexpr std::size_t kMaxHypotheses = 16;
  FixedVector<SessionAlignment, kMaxHypotheses> hypotheses_;   // newest last
  FixedVector<MatchEvent, kMaxHypotheses> held_matches_;       // one per hypothesis
  FixedVector<MatchEvent, kMaxHypotheses> confirmed_matches_;  // to send with this landmark
  void hold_for_release(const MatchEvent& held);
  SessionAlignment confirmed_;
  // True when `transform` maps `from` (loaded) onto `to` (this session)
  // within the drift limits for `driven` metres.
  bool agrees(const Pose2& transform, const Eigen::Vector2d& from, const Eigen::Vector2d& to, double yaw,
              double driven) const;
};

}  // namespace markloop
