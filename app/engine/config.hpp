// Every tunable of the sequence engine, in metres and seconds (never frames).
#pragma once

#include <cstddef>
#include <cstdint>

#include "app/engine/types.hpp"

namespace markloop {

// Limits of the engine's own, which validate() enforces. The ECU's settings
// table (app/ecu/settings.cpp) takes its ranges for these settings from
// here; its other ranges lie within validate()'s (tests/ecu/test_settings.cpp).
inline constexpr unsigned kMinSequenceLength = 2;  // kMaxSequenceLength: types.hpp
inline constexpr unsigned kMaxSkippedRows = 1;
inline constexpr double kMaxDistanceToleranceRel = 0.1;
inline constexpr double kMaxSettledLag_m = 1000.0;
inline constexpr std::size_t kMinDatabaseCapacity = 16;
inline constexpr std::size_t kMaxDatabaseCapacity = std::size_t{1} << 30;

struct TrackerConfig {
  // An observation joins an active track whose mean position is this close.
  double association_radius_m = 1.5;
  // A track that has not been seen for this long has left view: commit it.
  double commit_after_s = 0.5;
  // Tracks with fewer observations are dropped as spurious at commit.
  unsigned min_observations = 2;
  // Committed landmarks wait until the car is this far past them before they
  // are chained, so that landmarks enter sequences in along-track order.
  double release_lag_m = 15.0;
  // Sooner, once the car is this far past them and no marking still tracked
  // lies behind them: the order is then known. At or above release_lag_m it
  // never comes first. Negative: up to this far before the car draws level
  // with them, so a loop is sent as soon as its last marking has left view.
  double settled_lag_m = 15.0;
};

struct ChainConfig {
  unsigned k = 4;  // sequence length
  // Landmarks whose along-track stations lie within this distance of the
  // first landmark of a row form one row (markings side by side on lanes).
  double row_width_m = 1.5;
  // A gap longer than this between rows breaks the chain.
  double max_link_m = 200.0;
  // Rows a sequence may step over (0 or 1). A marking detected on one visit
  // and missed on the other otherwise breaks every sequence through it; with
  // 1, each new landmark also chains past one of its k - 1 earlier rows, so
  // the visit that saw the marking holds sequences without it as well.
  unsigned max_skipped_rows = 1;
};

struct MatchConfig {
  // Successive-landmark distances match when |d1 - d2| <= abs + rel * max(d1, d2).
  double distance_tolerance_abs_m = 0.5;
  double distance_tolerance_rel = 0.02;
  // The match must lie this far back along the drive (both must hold).
  double min_separation_m = 100.0;
  double min_separation_s = 10.0;
  // Rigid 2-D alignment of the k landmark pairs: largest accepted RMS residual.
  double max_residual_m = 0.5;
  // Index bins are this many tolerances wide (at least 3); wider bins mean
  // fewer probes but longer chains.
  double index_bin_tolerances = 4.0;
  // Bound on candidates examined per query, so latency stays bounded even on
  // pathologically repetitive roads.
  unsigned max_candidates_per_query = 64;
  // Odometry prior (off when max_drift_rel is 0): within one session, the
  // two visits' landmarks may lie apart in the world frame by at most what
  // the odometry can have drifted over the distance driven in between,
  // abs + rel * distance (and the alignment's rotation at most
  // yaw_abs + yaw_rel * distance). Look-alike places elsewhere are rejected.
  // Landmarks of a loaded map (negative stations) are not gated: their
  // world frame is another session's.
  double max_drift_rel = 0.0;
  double max_drift_abs_m = 5.0;
  double max_drift_yaw_abs_deg = 5.0;
  double max_drift_yaw_rel_deg_per_m = 0.01;
  // The two frames a loop names (where the car passed one of its markings
  // on each visit: the last, or else the one whose frames lie closest;
  // MatchEvent::framed) lie at most this far apart by the match's own
  // relative pose (0: no limit). Further apart, the routes parted before
  // the markings: they are the same, but the car was not at the same place,
  // which a loop detection says it was.
  double max_frame_distance_m = 0.0;
  // Places of a loaded map (an earlier session, whose world frame is
  // unrelated): a match into them is only a hypothesis of how the two
  // frames relate (the alignment); a later match, at least confirm_min_gap_m
  // and at most confirm_within_m of driving further, that agrees with one of
  // the recent hypotheses (same drift limits) confirms it, and from then on
  // matches must agree with the latest confirmed alignment. Look-alike
  // places give alignments that do not agree.
  bool confirm_loaded_places = false;
  double confirm_min_gap_m = 50.0;
  double confirm_within_m = 300.0;
  // Beyond far_after_m of driving between the two visits the odometry prior
  // admits too much of the map to tell look-alike places apart: a sequence
  // match is only sent once the run of matches continuing it spans far_run_m
  // of the drive (more than one intersection's markings, which look alike
  // everywhere); 0: no such wait.
  double far_after_m = 2500.0;
  double far_run_m = 0.0;
  // Place matching (app/engine/place_matcher.hpp), beside the sequences: when
  // this many of the landmarks released within the last place_window_m agree,
  // in any order, with landmarks stored where the odometry puts them (within
  // the drift limits above, at most place_search_m), the place is a loop,
  // unless another place within place_distinct_m (at least place_search_m)
  // fits as well. 0 is off: the
  // paper's sequences alone.
  unsigned place_landmarks = 0;
  double place_window_m = 60.0;
  double place_search_m = 40.0;
  double place_distinct_m = 150.0;
  // A place's labels must be rare enough: the sum over its pairs of -log2
  // of each label's share of the landmarks seen so far (0: any labels).
  double place_min_bits = 0.0;
  // A place of two pairs, fewer than place_landmarks, counts when its labels
  // give at least this many bits, it fits within 0.1 m, the cars drove one
  // road at both pairs, no rival of two pairs or more fits, and no more than
  // place_pair_max_unseen stored landmarks lay, aligned, where the car
  // looked on its way in without anything of their label seen there. A
  // place of more pairs whose labels give fewer than place_min_bits needs
  // these bits and fit too, and no stored landmark unseen (0: a place needs
  // place_landmarks pairs and place_min_bits).
  double place_pair_min_bits = 0.0;
  unsigned place_pair_max_unseen = 0;
  // Where the car surely sees a marking (the observations' ground area,
  // less its edges): from near to near + depth ahead of the car, and to
  // either side.
  double place_view_near_m = 6.5;
  double place_view_depth_m = 7.5;
  double place_view_side_m = 4.5;
  // A place's rigid fit must be at most this far off (RMS), and within
  // max_residual_m: a constellation has no order and no distances checked
  // before its fit, and a far pair shifted to a look-alike fits roughly.
  double place_max_residual_m = 0.5;
  // Places are matched only where the two visits lie at most this far apart
  // along the drive: further, the drift limits admit look-alikes.
  double place_within_m = 2500.0;
  // A place of two or of common labels whose cars drove opposite ways (an
  // intersection's crosswalks and stop lines seen from the other side) looks
  // like every intersection of its layout: only the odometry tells them
  // apart, so it is matched only between visits at most this far apart.
  double place_opposite_within_m = 2500.0;
};

// What the odometry can have drifted over `driven_m` of driving, by the
// drift limits of `c`: metres apart, and degrees turned.
inline double drift_allowed_m(const MatchConfig& c, double driven_m) {
  return c.max_drift_abs_m + c.max_drift_rel * driven_m;
}
inline double drift_allowed_deg(const MatchConfig& c, double driven_m) {
  return c.max_drift_yaw_abs_deg + c.max_drift_yaw_rel_deg_per_m * driven_m;
}

struct DatabaseConfig {
  std::size_t landmark_capacity = std::size_t{1} << 18;
  std::size_t sequence_capacity = std::size_t{1} << 20;
};

struct EngineConfig {
  TrackerConfig tracker;
  ChainConfig chain;
  MatchConfig match;
  DatabaseConfig database;
};

// Returns nullptr when the configuration is usable, else what is wrong.
const char* validate(const EngineConfig& config);

}  // namespace markloop
