#include "app/engine/sequence_engine.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

#include <Eigen/Core>

#include "app/common/units.hpp"
#include "app/engine/rigid_alignment.hpp"

namespace markloop {

const char* validate(const EngineConfig& c) {
  const auto finite_positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  const auto finite_non_negative = [](double v) { return std::isfinite(v) && v >= 0.0; };
  // The messages name the limits of app/engine/config.hpp.
  static_assert(kMinSequenceLength == 2 && kMaxSequenceLength == 10 && kMaxSkippedRows == 1);
  static_assert(kMaxDistanceToleranceRel == 0.1 && kMinDatabaseCapacity == 16 && kMaxSettledLag_m == 1000.0);
  static_assert(kMaxDatabaseCapacity == std::size_t{1} << 30);
  if (c.chain.k < kMinSequenceLength || c.chain.k > kMaxSequenceLength) return "k must be between 2 and 10";
  if (c.chain.max_skipped_rows > kMaxSkippedRows) return "rows skipped must be 0 or 1";
  if (!finite_positive(c.tracker.association_radius_m))
    return "association radius must be a positive number of metres";
  if (!finite_positive(c.tracker.commit_after_s)) return "commit delay must be a positive number of seconds";
  if (c.tracker.min_observations < 1) return "minimum observations must be at least 1";
  if (!finite_non_negative(c.tracker.release_lag_m))
    return "release lag must be a non-negative number of metres";
  if (!std::isfinite(c.tracker.settled_lag_m) || std::abs(c.tracker.settled_lag_m) > kMaxSettledLag_m)
    return "settled lag must be a number of metres between -1000 and 1000";
  if (!finite_non_negative(c.chain.row_width_m)) return "row width must be a non-negative number of metres";
  if (!std::isfinite(c.chain.max_link_m) || c.chain.max_link_m <= c.chain.row_width_m)
    return "maximum link distance must exceed the row width";
  if (!finite_positive(c.match.distance_tolerance_abs_m))
    return "absolute distance tolerance must be a positive number of metres";
  if (!std::isfinite(c.match.distance_tolerance_rel) || c.match.distance_tolerance_rel < 0.0 ||
      c.match.distance_tolerance_rel > kMaxDistanceToleranceRel)
    return "relative distance tolerance must be between 0 and 0.1";
  if (!finite_non_negative(c.match.min_separation_m) || !finite_non_negative(c.match.min_separation_s))
    return "minimum separation must be non-negative";
  if (!finite_positive(c.match.max_residual_m)) return "maximum residual must be a positive number of metres";
  // Narrower bins could let a tolerance interval straddle three bins.
  if (!std::isfinite(c.match.index_bin_tolerances) || c.match.index_bin_tolerances < 3.0 ||
      c.match.index_bin_tolerances > 1000.0)
    return "index bin width must be between 3 and 1000 tolerances";
  if (c.match.max_candidates_per_query < 1) return "candidate limit must be at least 1";
  if (!finite_non_negative(c.match.max_drift_rel) || !finite_non_negative(c.match.max_drift_abs_m) ||
      !finite_non_negative(c.match.max_drift_yaw_abs_deg) ||
      !finite_non_negative(c.match.max_drift_yaw_rel_deg_per_m))
    return "drift limits must be non-negative";
  if (!finite_non_negative(c.match.max_frame_distance_m)) return "frame distance limit must be non-negative";
  if (!finite_non_negative(c.match.confirm_within_m) || !finite_non_negative(c.match.confirm_min_gap_m))
    return "confirmation distances must be non-negative";
  if (!finite_non_negative(c.match.far_after_m) || !finite_non_negative(c.match.far_run_m))
    return "far revisit distances must be non-negative";
  if (c.match.place_landmarks != 0 &&
      (c.match.place_landmarks < kMinSequenceLength || c.match.place_landmarks > kMaxSequenceLength))
    return "place landmarks must be 0 (off) or between 2 and 10";
  if (!finite_non_negative(c.match.place_within_m) || !finite_non_negative(c.match.place_opposite_within_m))
    return "place distance along the drive must be non-negative";
  if (!finite_positive(c.match.place_max_residual_m))
    return "place residual must be a positive number of metres";
  if (!finite_non_negative(c.match.place_min_bits) || c.match.place_min_bits > 1000.0)
    return "place evidence must lie between 0 and 1000 bits";
  if (!finite_non_negative(c.match.place_pair_min_bits) || c.match.place_pair_min_bits > 1000.0)
    return "two-marking place evidence must lie between 0 and 1000 bits";
  if (!finite_non_negative(c.match.place_view_near_m) || !finite_positive(c.match.place_view_depth_m) ||
      !finite_non_negative(c.match.place_view_side_m) ||
      c.match.place_view_near_m + c.match.place_view_depth_m + c.match.place_view_side_m > 1000.0)
    return "the view of a place of two must lie ahead within 1000 m, and be deeper than 0 m";
  if (!finite_positive(c.match.place_window_m) || !finite_positive(c.match.place_search_m))
    return "place window and search distance must be positive numbers of metres";
  if (!finite_positive(c.match.place_distinct_m) || c.match.place_distinct_m > 10000.0)
    return "place distinctness radius must lie between 0 and 10000 m";
  if (c.database.landmark_capacity < kMinDatabaseCapacity ||
      c.database.landmark_capacity > kMaxDatabaseCapacity)
    return "landmark capacity must be between 16 and 2^30";
  if (c.database.sequence_capacity < kMinDatabaseCapacity ||
      c.database.sequence_capacity > kMaxDatabaseCapacity)
    return "sequence capacity must be between 16 and 2^30";
  return nullptr;
}

SequenceEngine::SequenceEngine(const EngineConfig& config)
    : config_(config),
      tracker_(config.tracker),
      database_(config.database, config.match, config.chain.k),
      places_(config.match),
      // The history must reach back past the release lag, with room for
      // landmarks released late; a few centimetres apart is precise enough.
      history_spacing_m_(std::max(0.02, (config.tracker.release_lag_m + 25.0) / kFrameHistory)) {}

void SequenceEngine::process_frame(const FrameInput& frame, std::span<const Observation> observations,
                                   MatchSink& sink) {
  ++counters_.frames;
  if (counters_.frames > 1 && frame.t < last_t_) ++counters_.frames_out_of_order;
  last_t_ = frame.t;

  if (frame.has_pose) {
    if (have_previous_pose_)
      odometer_ += std::hypot(frame.pose.x - previous_pose_.x, frame.pose.y - previous_pose_.y);
    previous_pose_ = frame.pose;
    have_previous_pose_ = true;
    remember_frame(frame);
    if (places_.enabled()) places_.remember_pose(frame.pose, odometer_);
    represent_passed_landmarks(sink);
  }
  tracker_.observe(frame, odometer_,
                   observations.first(std::min(observations.size(), kMaxObservationsPerFrame)));
  if (observations.size() > kMaxObservationsPerFrame)
    counters_.observations_over_limit += observations.size() - kMaxObservationsPerFrame;
  commit_and_release(frame.t, false, sink);
}

void SequenceEngine::remember_frame(const FrameInput& frame) {
  if (history_size_ > 0 && odometer_ < history_at(history_size_ - 1).odometer + history_spacing_m_) return;
  const PassingFrame entry{frame.frame, frame.t, odometer_, frame.pose};
  if (history_size_ < kFrameHistory) {
    history_[(history_oldest_ + history_size_++) % kFrameHistory] = entry;
  } else {
    history_[history_oldest_] = entry;
    history_oldest_ = (history_oldest_ + 1) % kFrameHistory;
  }
}

bool SequenceEngine::represent_by_passing_frame(Landmark& landmark) {
  if (history_size_ == 0) return false;
  // The car's closest approach to the landmark among the frames remembered
  // around its station: level with it on a straight road, and still the
  // same spot on every visit where the car turns away at a corner (where
  // "odometer = station" would pick a point metres down the other street).
  // Odometers rise along the history: find where the window starts, then
  // look only inside it.
  std::size_t first = 0, last = history_size_;
  while (first < last) {
    const std::size_t mid = (first + last) / 2;
    if (history_at(mid).odometer < landmark.station - kPassingWindow_m)
      first = mid + 1;
    else
      last = mid;
  }
  std::size_t best = history_size_;
  double best_sq = 0.0;
  for (std::size_t i = first; i < history_size_; ++i) {
    const PassingFrame& f = history_at(i);
    if (f.odometer > landmark.station + kPassingWindow_m) break;
    const double dx = f.pose.x - landmark.x, dy = f.pose.y - landmark.y;
    const double d_sq = dx * dx + dy * dy;
    if (best == history_size_ || d_sq < best_sq) {
      best = i;
      best_sq = d_sq;
    }
  }
  const bool passed = history_at(history_size_ - 1).odometer >= landmark.station;
  if (best == history_size_) {
    // Nothing remembered that near: long gone (a crawl filled the history),
    // or far ahead at the end of a drive.
    if (passed) ++counters_.passing_frames_forgotten;
    best = passed ? 0 : history_size_ - 1;
  }
  const PassingFrame& passing = history_at(best);
  landmark.last_frame = std::max(landmark.first_frame, passing.frame);
  landmark.t = passing.t;
  // The facing was read against the car's heading where it last saw the
  // marking; it turns with the heading it is now read against.
  if (landmark.facing != Facing::kAny &&
      std::abs(wrap_angle(passing.pose.yaw - landmark.car_yaw)) > 0.5 * std::numbers::pi)
    landmark.facing = landmark.facing == Facing::kAlong ? Facing::kAgainst : Facing::kAlong;
  landmark.car_x = static_cast<float>(passing.pose.x);
  landmark.car_y = static_cast<float>(passing.pose.y);
  landmark.car_yaw = static_cast<float>(passing.pose.yaw);
  return passed;
}

void SequenceEngine::represent_passed_landmarks(MatchSink& sink) {
  for (std::size_t i = 0; i < unpassed_.size();) {
    const Landmark* stored = database_.landmark(unpassed_[i]);
    if (stored != nullptr && odometer_ < stored->station + kPassedBy_m) {
      ++i;
      continue;
    }
    if (stored != nullptr) {
      Landmark passed = *stored;
      (void)represent_by_passing_frame(passed);
      (void)database_.set_frame(passed);
      places_.set_frame(passed);
      if (passed.id == place_retry_ && places_.newest() == passed.id) (void)match_place(sink);
    }
    if (unpassed_[i] == place_retry_) place_retry_ = kNoLandmark;
    unpassed_.erase_at(i);
  }
}

void SequenceEngine::flush(MatchSink& sink) {
  commit_and_release(last_t_, true, sink);
}

void SequenceEngine::break_chains(MatchSink& sink) {
  flush(sink);
  rows_.clear();
  places_.forget();
  unpassed_.clear();  // the frames to come are not on the same path
  place_retry_ = kNoLandmark;
  have_previous_pose_ = false;
  ++counters_.chain_breaks;
}

void SequenceEngine::commit_and_release(double now, bool all, MatchSink& sink) {
  for (;;) {
    committed_.clear();
    const bool done = tracker_.commit(now, all, committed_);
    for (const Landmark& landmark : committed_) {
      if (!landmark.has_car_pose) {
        // Without a pose there is no odometer to wait for: release at once.
        release(landmark, all, sink);
        continue;
      }
      if (pending_.full()) {
        ++counters_.pending_overflows;
        release(pending_[0], all, sink);
        pending_.erase_at(0);
      }
      // Insertion sort by station: the list is short and nearly sorted.
      pending_.push_back(landmark);
      for (std::size_t i = pending_.size() - 1; i > 0 && pending_[i - 1].station > pending_[i].station; --i)
        std::swap(pending_[i - 1], pending_[i]);
    }
    if (done) break;
  }
  // Every landmark still to come lies beyond the car or beyond an active
  // track: one settled that far behind enters in order.
  const double settled =
      std::min(odometer_ - config_.tracker.settled_lag_m, tracker_.lowest_active_station());
  const double released = std::max(odometer_ - config_.tracker.release_lag_m, settled);
  while (!pending_.empty() && (all || pending_[0].station <= released)) {
    release(pending_[0], all, sink);
    pending_.erase_at(0);
  }
}

void SequenceEngine::release(Landmark landmark, bool flushing, MatchSink& sink) {
  bool may_match = true, passed = true;
  if (landmark.has_car_pose) {
    // One released before the car reaches it (a negative settled lag) has
    // left view: it is final. One flushed ahead may still have been in view.
    passed = represent_by_passing_frame(landmark);
    may_match = passed || !flushing;
    if (!may_match) ++counters_.landmarks_flushed_ahead;
  } else {
    // No odometry: the travelled distance is the path through the markings.
    landmark.station =
        have_released_ ? last_released_.station + planar_distance(landmark, last_released_) : 0.0;
  }
  const LandmarkId id = database_.add_landmark(landmark);
  if (!passed && !flushing) {
    // Released ahead of the car; more than kMaxPending such landmarks at once
    // are more than the tracker holds: the oldest keeps the frame it has.
    if (unpassed_.full()) unpassed_.erase_at(0);
    (void)unpassed_.push_back(id);
  }
  ++counters_.landmarks_released;
  last_released_ = landmark;
  have_released_ = true;

  const ChainConfig& chain_config = config_.chain;
  if (rows_.empty() || landmark.station > rows_.back().anchor_station + chain_config.row_width_m) {
    if (!rows_.empty() && landmark.station - rows_.back().anchor_station > chain_config.max_link_m) {
      rows_.clear();
      ++counters_.chain_breaks;
    }
    if (rows_.size() == chain_config.k + chain_config.max_skipped_rows) rows_.erase_at(0);
    rows_.push_back(Row{landmark.station, {}});
  }
  if (places_.enabled() && landmark.has_car_pose) places_.remember(*database_.landmark(id));
  bool matched = false;
  if (!rows_.back().members.push_back(id))
    ++counters_.landmarks_unchained;
  else if (rows_.size() >= chain_config.k)
    matched = chain(id, may_match, sink);
  // A place whose frames lie apart only because the car has not reached its
  // newest marking yet is tried again once it has (represent_passed_landmarks).
  if (!matched && may_match && match_place(sink) == PlaceOutcome::kFramesApart && !passed) place_retry_ = id;
}

SequenceEngine::PlaceOutcome SequenceEngine::match_place(MatchSink& sink) {
  if (!places_.enabled() || !places_.match(database_, best_)) return PlaceOutcome::kNone;
  set_relative_pose(best_, Framing::kClosestCars);
  if (best_.has_relative_pose &&
      frames_too_far_apart(std::hypot(best_.relative_pose.x, best_.relative_pose.y))) {
    ++counters_.candidates_rejected_frames_apart;
    return PlaceOutcome::kFramesApart;
  }
  ++counters_.matches;
  ++counters_.place_matches;
  sink.on_match(best_);
  return PlaceOutcome::kSent;
}

bool SequenceEngine::chain(LandmarkId id, bool may_match, MatchSink& sink) {
  const unsigned k = config_.chain.k;
  // The rows before the new landmark's, oldest first.
  const unsigned earlier = static_cast<unsigned>(rows_.size()) - 1;
  // Variant 0 takes the k - 1 rows just before; variant v (1 .. k - 1), when
  // one more row is kept, takes the k rows before but the v-th newest: the
  // sequences a visit that missed that row's marking would make. They are
  // all stored; the skipping ones are only queried when no plain one matched,
  // so two visits that both saw everything give one match, as before.
  const unsigned variants = earlier == k ? k : 1;
  std::array<std::size_t, kMaxSequenceLength> row_of{};  // rows_ index per position

  std::array<std::size_t, kMaxSequenceLength> choice{};
  std::array<LandmarkId, kMaxSequenceLength> ids{};
  ids[k - 1] = id;
  const std::span<const LandmarkId> sequence(ids.data(), k);

  MatchEvent candidate;
  bool found = false, found_over_skipped_row = false;
  unsigned made = 0;
  for (unsigned variant = 0; variant < variants; ++variant) {
    const std::size_t first_row = variant == 0 ? earlier - (k - 1) : earlier - k;
    const std::size_t skipped = variant == 0 ? rows_.size() : earlier - variant;  // none: past the end
    for (std::size_t r = 0, row = first_row; r + 1 < k; ++row)
      if (row != skipped) row_of[r++] = row;
    const bool query = may_match && (variant == 0 || !found);
    // One landmark from each chosen row, then the new one: every combination,
    // so a marking missed on one lane leaves the chains through other lanes.
    choice.fill(0);
    for (;;) {
      for (unsigned r = 0; r + 1 < k; ++r) ids[r] = rows_[row_of[r]].members[choice[r]];
      if (made == kMaxSequencesPerLandmark) {
        ++counters_.sequences_capped;
      } else {
        ++made;
        // One shape serves the query and the insertion.
        SequenceShape shape;
        if (database_.shape_of(sequence, shape)) {
          if (query && match(sequence, shape, variant > 0, candidate) &&
              (!found || candidate.residual_m < best_.residual_m)) {
            best_ = candidate;
            found = true;
            found_over_skipped_row = variant > 0;
          }
          database_.add_sequence(sequence, shape);
          ++counters_.sequences_created;
          if (variant > 0) ++counters_.sequences_over_skipped_row;
        }
      }
      unsigned r = 0;
      while (r + 1 < k && choice[r] + 1 == rows_[row_of[r]].members.size()) choice[r++] = 0;
      if (r + 1 >= k) break;
      ++choice[r];
    }
  }
  // Matches into a loaded map held back until its alignment was confirmed
  // (by a sequence ending at this landmark) go out first, oldest first.
  for (const MatchEvent& held : confirmed_matches_) {
    ++counters_.matches;
    ++counters_.loaded_hypotheses_sent;
    sink.on_match(held);
  }
  confirmed_matches_.clear();
  if (found) {
    extend_closure_run(best_);
    if (waits_for_longer_run(best_)) {
      ++counters_.matches_held_far;
      return true;
    }
    ++counters_.matches;
    if (found_over_skipped_row) ++counters_.matches_over_skipped_row;
    sink.on_match(best_);
  }
  return found;
}

void SequenceEngine::hold_for_release(const MatchEvent& held) {
  // One per query landmark: the best fitting.
  for (MatchEvent& queued : confirmed_matches_) {
    if (queued.query[queued.k - 1].id != held.query[held.k - 1].id) continue;
    if (held.residual_m < queued.residual_m) queued = held;
    return;
  }
  (void)confirmed_matches_.push_back(held);
}

bool SequenceEngine::agrees(const Pose2& transform, const Eigen::Vector2d& from, const Eigen::Vector2d& to,
                            double yaw, double driven) const {
  const MatchConfig& mc = config_.match;
  const double c = std::cos(transform.yaw), s = std::sin(transform.yaw);
  const Eigen::Vector2d predicted(transform.x + c * from.x() - s * from.y(),
                                  transform.y + s * from.x() + c * from.y());
  const double turned = std::abs(wrap_angle(yaw - transform.yaw)) * kDegreesPerRadian;
  driven = std::max(driven, 0.0);
  return (predicted - to).norm() <= drift_allowed_m(mc, driven) && turned <= drift_allowed_deg(mc, driven);
}

bool SequenceEngine::match(std::span<const LandmarkId> query, const SequenceShape& shape,
                           bool over_skipped_row, MatchEvent& best) {
  ++counters_.queries;
  const Query q = load_query(query, shape, over_skipped_row, best);
  bool found = false;
  unsigned verified = 0;
  bool limited = false;
  Candidate candidate;
  database_.for_each_match(shape, config_.match.max_candidates_per_query, limited,
                           [&](std::span<const LandmarkId> ids) {
                             if (verify_candidate(q, ids, candidate)) {
                               ++verified;
                               keep_if_best(candidate, found, best);
                             }
                             return true;
                           });
  if (limited) ++counters_.candidate_limit_hits;
  if (!found) return false;

  best.k = config_.chain.k;
  best.verified_candidates = verified;
  best.aligned_pairs = best.k;
  set_relative_pose(best);
  return true;
}

SequenceEngine::Query SequenceEngine::load_query(std::span<const LandmarkId> ids, const SequenceShape& shape,
                                                 bool over_skipped_row, MatchEvent& best) const {
  Query q{ids, &shape, over_skipped_row, best.query.data(), {}};
  for (unsigned i = 0; i < config_.chain.k; ++i) {
    best.query[i] = *database_.landmark(ids[i]);
    q.points[i] = {best.query[i].x, best.query[i].y};
  }
  return q;
}

bool SequenceEngine::verify_candidate(const Query& query, std::span<const LandmarkId> ids,
                                      Candidate& candidate) {
  const unsigned k = config_.chain.k;
  const MatchConfig& mc = config_.match;
  ++counters_.candidates;
  if (too_recent(query, ids)) {
    ++counters_.candidates_too_recent;
    return false;
  }
  measure_candidate(query, ids, candidate);
  candidate.fit = fit_rigid_2d({candidate.points.data(), k}, {query.points.data(), k});
  if (candidate.fit.rms_residual > mc.max_residual_m) {
    ++counters_.candidates_rejected_residual;
    return false;
  }
  if (frames_too_far_apart(query, candidate)) {
    ++counters_.candidates_rejected_frames_apart;
    return false;
  }
  // Places of a loaded map were moved before this session's start.
  const double first_station = database_.landmark(ids[0])->station;
  if (mc.confirm_loaded_places && first_station < 0.0 && !accept_into_loaded_map(query, candidate))
    return false;
  if (mc.max_drift_rel > 0.0 && first_station >= 0.0 && beyond_odometry_prior(query, candidate)) {
    ++counters_.candidates_rejected_drift;
    return false;
  }
  return true;
}

bool SequenceEngine::too_recent(const Query& query, std::span<const LandmarkId> ids) const {
  const MatchConfig& mc = config_.match;
  const Landmark& candidate_last = *database_.landmark(ids[config_.chain.k - 1]);
  return candidate_last.station > query.first().station - mc.min_separation_m ||
         candidate_last.t > query.first().t - mc.min_separation_s;
}

void SequenceEngine::measure_candidate(const Query& query, std::span<const LandmarkId> ids,
                                       Candidate& candidate) const {
  candidate.ids = ids;
  candidate.normalised_error = 0.0;
  for (unsigned i = 0; i < config_.chain.k; ++i) {
    const Landmark& landmark = *database_.landmark(ids[i]);
    candidate.points[i] = {landmark.x, landmark.y};
    if (i > 0) {
      const double d = (candidate.points[i] - candidate.points[i - 1]).norm();
      const double expected = query.shape->distances[i];
      const double tolerance = database_.quantiser().tolerance(d, expected);
      candidate.normalised_error += std::abs(d - expected) / tolerance;
    }
  }
}

bool SequenceEngine::frames_too_far_apart(const Query& query, const Candidate& candidate) const {
  if (config_.match.max_frame_distance_m <= 0.0) return false;
  // Any pair's frames will do (framed_pair names them).
  for (unsigned i = 0; i < config_.chain.k; ++i)
    if (!frames_too_far_apart(
            frames_apart(candidate.fit.transform, query.landmarks[i], *database_.landmark(candidate.ids[i]))))
      return false;
  return true;
}

bool SequenceEngine::frames_too_far_apart(const std::optional<double>& apart_m) const {
  const double limit = config_.match.max_frame_distance_m;
  return limit > 0.0 && apart_m && *apart_m > limit;
}

bool SequenceEngine::accept_into_loaded_map(const Query& query, const Candidate& candidate) {
  // Until the loaded map's alignment is known, only sequences without a gap
  // may propose it: a skipped row is one more way for a look-alike place to
  // fit, and a rival hypothesis holds the true one back.
  if (query.over_skipped_row && !confirmed_.valid) return false;
  // A place of a loaded map has no odometry prior: it must agree over k + 1
  // rows (this sequence and the one a row back, both verified)...
  if (!continues_loaded_sequence(query, candidate)) {
    ++counters_.loaded_single_sequences;
    return false;
  }
  // ...and its alignment must agree with how the two sessions' frames are
  // known (or about to be found) to relate.
  const SessionAlignment proposed = proposed_alignment(query, candidate);
  if (confirmed_.valid) return agrees_with_confirmed(proposed);
  return confirm_by_hypotheses(query, candidate, proposed);
}

bool SequenceEngine::continues_loaded_sequence(const Query& query, const Candidate& candidate) {
  const unsigned k = config_.chain.k;
  const bool continues =
      std::find(loaded_pairs_.begin(), loaded_pairs_.end(),
                LandmarkPair{query.ids[k - 2], candidate.ids[k - 2]}) != loaded_pairs_.end();
  // Remembered so that the sequence a row further on can continue this one.
  if (loaded_pairs_.full()) loaded_pairs_.erase_at(0);
  (void)loaded_pairs_.push_back({query.ids[k - 1], candidate.ids[k - 1]});
  return continues;
}

SequenceEngine::SessionAlignment SequenceEngine::proposed_alignment(const Query& query,
                                                                    const Candidate& candidate) const {
  const unsigned k = config_.chain.k;
  Eigen::Vector2d query_centre = Eigen::Vector2d::Zero(), candidate_centre = Eigen::Vector2d::Zero();
  for (unsigned i = 0; i < k; ++i) {
    query_centre += query.points[i] / k;
    candidate_centre += candidate.points[i] / k;
  }
  return {true, candidate.fit.transform, query.first().station, candidate_centre, query_centre};
}

bool SequenceEngine::agrees_with_confirmed(const SessionAlignment& proposed) {
  if (!agrees(confirmed_.transform, proposed.from, proposed.to, proposed.transform.yaw,
              proposed.station - confirmed_.station)) {
    ++counters_.loaded_rejected;
    return false;
  }
  confirmed_ = {true, proposed.transform, proposed.station};
  return true;
}

bool SequenceEngine::confirm_by_hypotheses(const Query& query, const Candidate& candidate,
                                           const SessionAlignment& proposed) {
  // Confirmed by earlier hypotheses that agree and rest on other landmarks (at
  // least a row further back along the drive), provided no rival alignment,
  // one this match disagrees with, is as well supported: on look-alike blocks
  // a wrong alignment can find a second match too, but not more than the true
  // one. The matches of the agreeing hypotheses, held back so far, are sent
  // now.
  unsigned support = 0;
  for (const SessionAlignment& h : hypotheses_) support += supports(h, proposed) ? 1 : 0;
  const unsigned rival_support = support > 0 ? strongest_rival_support(proposed) : 0;
  // This match plus the hypotheses it agrees with, against the rival.
  const bool confirmed = support > 0 && support + 1 > rival_support;
  if (support > 0 && !confirmed) ++counters_.loaded_rivalled;
  if (!confirmed) {
    hold_hypothesis(query, candidate, proposed);
    return false;
  }
  for (std::size_t h = 0; h < hypotheses_.size(); ++h)
    if (supports(hypotheses_[h], proposed)) hold_for_release(held_matches_[h]);
  confirmed_ = {true, proposed.transform, proposed.station};
  hypotheses_.clear();
  held_matches_.clear();
  return true;
}

bool SequenceEngine::supports(const SessionAlignment& hypothesis, const SessionAlignment& proposed) const {
  const MatchConfig& mc = config_.match;
  const double driven = proposed.station - hypothesis.station;
  return driven >= mc.confirm_min_gap_m && driven <= mc.confirm_within_m &&
         agrees(hypothesis.transform, proposed.from, proposed.to, proposed.transform.yaw, driven);
}

unsigned SequenceEngine::strongest_rival_support(const SessionAlignment& proposed) const {
  const double within = config_.match.confirm_within_m;
  unsigned strongest = 0;
  for (std::size_t g = 0; g < hypotheses_.size(); ++g) {
    const SessionAlignment& rival = hypotheses_[g];
    const double driven = proposed.station - rival.station;
    if (driven > within || agrees(proposed.transform, rival.from, rival.to, rival.transform.yaw, driven))
      continue;
    unsigned its = 1;
    for (std::size_t h = 0; h < hypotheses_.size(); ++h) {
      const SessionAlignment& other = hypotheses_[h];
      const double apart = std::abs(rival.station - other.station);
      if (h != g && apart <= within &&
          agrees(rival.transform, other.from, other.to, other.transform.yaw, apart))
        ++its;
    }
    strongest = std::max(strongest, its);
  }
  return strongest;
}

void SequenceEngine::hold_hypothesis(const Query& query, const Candidate& candidate,
                                     const SessionAlignment& proposed) {
  const unsigned k = config_.chain.k;
  if (hypotheses_.full()) {
    hypotheses_.erase_at(0);
    held_matches_.erase_at(0);
  }
  hypotheses_.push_back(proposed);
  MatchEvent& held = held_matches_.push_back_slot();
  held.k = k;
  for (unsigned i = 0; i < k; ++i) {
    held.query[i] = query.landmarks[i];
    held.match[i] = *database_.landmark(candidate.ids[i]);
  }
  held.alignment = candidate.fit.transform;
  held.residual_m = candidate.fit.rms_residual;
  held.score = score_of(candidate);
  held.verified_candidates = 1;
  held.aligned_pairs = k;
  set_relative_pose(held);
  ++counters_.loaded_hypotheses;
}

bool SequenceEngine::beyond_odometry_prior(const Query& query, const Candidate& candidate) const {
  // Same session: the places' world positions differ by the odometry's drift only.
  const unsigned k = config_.chain.k;
  const MatchConfig& mc = config_.match;
  Eigen::Vector2d query_centre = Eigen::Vector2d::Zero(), candidate_centre = Eigen::Vector2d::Zero();
  for (unsigned i = 0; i < k; ++i) {
    query_centre += query.points[i];
    candidate_centre += candidate.points[i];
  }
  const double driven = query.first().station - database_.landmark(candidate.ids[k - 1])->station;
  const double apart = (query_centre - candidate_centre).norm() / k;
  const double turned = std::abs(candidate.fit.transform.yaw) * kDegreesPerRadian;
  return apart > drift_allowed_m(mc, driven) || turned > drift_allowed_deg(mc, driven);
}

double SequenceEngine::score_of(const Candidate& candidate) const {
  return std::clamp(1.0 - candidate.normalised_error / (config_.chain.k - 1), 0.0, 1.0);
}

void SequenceEngine::keep_if_best(const Candidate& candidate, bool& found, MatchEvent& best) const {
  if (found && !(candidate.fit.rms_residual < best.residual_m)) return;
  found = true;
  for (unsigned i = 0; i < config_.chain.k; ++i) best.match[i] = *database_.landmark(candidate.ids[i]);
  best.alignment = candidate.fit.transform;
  best.residual_m = candidate.fit.rms_residual;
  best.score = score_of(candidate);
}

unsigned SequenceEngine::framed_pair(const MatchEvent& event, Framing framing) const {
  // The newest pair's frames lie apart when its query landmark was released
  // before the car reached it and the stored one was passed: then, as for a
  // place always, the pair whose cars, aligned, lie closest (newest first).
  const auto apart = [&](unsigned pair) {
    return frames_apart(event.alignment, event.query[pair], event.match[pair])
        .value_or(std::numeric_limits<double>::infinity());
  };
  unsigned best = event.k - 1;
  double best_apart = apart(best);
  if (framing == Framing::kNewest && !frames_too_far_apart(best_apart)) return best;
  for (unsigned i = event.k - 1; i-- > 0;)
    if (const double a = apart(i); a < best_apart) best = i, best_apart = a;
  return best;
}

std::optional<double> SequenceEngine::frames_apart(const Pose2& alignment, const Landmark& query,
                                                   const Landmark& match) {
  const std::optional<Pose2> relative = relative_car_pose(alignment, query, match);
  if (!relative) return std::nullopt;
  return std::hypot(relative->x, relative->y);
}

void SequenceEngine::set_relative_pose(MatchEvent& event, Framing framing) const {
  event.framed = framed_pair(event, framing);
  const std::optional<Pose2> relative =
      relative_car_pose(event.alignment, event.query[event.framed], event.match[event.framed]);
  event.has_relative_pose = relative.has_value();
  if (relative) event.relative_pose = *relative;
}

bool SequenceEngine::waits_for_longer_run(const MatchEvent& event) const {
  const MatchConfig& mc = config_.match;
  const double then = event.match[event.k - 1].station;
  // A loaded map's places (negative stations) are confirmed their own way.
  if (mc.far_run_m <= 0.0 || then < 0.0) return false;
  const double run = event.query[event.k - 1].station - closure_run_start_station_;
  return event.query[0].station - then > mc.far_after_m && run < mc.far_run_m;
}

void SequenceEngine::extend_closure_run(MatchEvent& event) {
  const unsigned k = event.k;
  const auto pair_at = [&](unsigned i) { return LandmarkPair{event.query[i].id, event.match[i].id}; };
  // The same closure goes on when one of this event's earlier pairs is in
  // the run (the sequences through a row of markings side by side end on
  // any of them): the run keeps the earlier pairs too.
  bool continues = false;
  for (unsigned i = 0; i + 1 < k; ++i)
    for (const LandmarkPair& p : closure_run_)
      continues = continues || (p.query == event.query[i].id && p.match == event.match[i].id);
  const auto start_run_here = [&] {
    closure_run_start_station_ = event.query[0].station;
    closure_run_.clear();
    for (unsigned i = 0; i < k; ++i) (void)closure_run_.push_back(pair_at(i));
  };
  if (!continues) {
    start_run_here();
    return;
  }
  for (unsigned i = 0; i < k; ++i) {
    const LandmarkPair pair = pair_at(i);
    bool known = false;
    for (const LandmarkPair& p : closure_run_) known = known || p.query == pair.query;
    if (known) continue;
    if (closure_run_.full()) closure_run_.erase_at(0);
    (void)closure_run_.push_back(pair);
  }
  std::array<Eigen::Vector2d, kMaxRunPairs> from{}, to{};
  std::size_t n = 0;
  for (const LandmarkPair& p : closure_run_) {
    const Landmark* q = database_.landmark(p.query);
    const Landmark* m = database_.landmark(p.match);
    if (q == nullptr || m == nullptr) continue;
    from[n] = {m->x, m->y};
    to[n] = {q->x, q->y};
    ++n;
  }
  if (n <= k) return;
  const RigidFit fit = fit_rigid_2d({from.data(), n}, {to.data(), n});
  if (fit.rms_residual > config_.match.max_residual_m) {
    // The run no longer fits one rigid transform: start again from here.
    start_run_here();
    return;
  }
  event.alignment = fit.transform;
  event.residual_m = fit.rms_residual;
  event.aligned_pairs = static_cast<unsigned>(n);
  set_relative_pose(event);
  ++counters_.closures_extended;
}

}  // namespace markloop
