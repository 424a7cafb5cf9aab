#include "app/engine/landmark_tracker.hpp"

#include <cmath>
#include <limits>

namespace markloop {

void LandmarkTracker::observe(const FrameInput& frame, double odometer,
                              std::span<const Observation> observations) {
  for (Track& track : tracks_) track.updated = false;
  const double radius_sq = config_.association_radius_m * config_.association_radius_m;

  for (const Observation& obs : observations) {
    ++counters_.observations;
    if (!std::isfinite(obs.x) || !std::isfinite(obs.y) || !std::isfinite(obs.weight) || obs.weight <= 0.0f) {
      ++counters_.observations_rejected;
      continue;
    }
    Track* best = nullptr;
    double best_sq = radius_sq;
    for (Track& track : tracks_) {
      if (track.updated) continue;
      const double dx = track.sum_x / track.sum_weight - obs.x;
      const double dy = track.sum_y / track.sum_weight - obs.y;
      const double d_sq = dx * dx + dy * dy;
      if (d_sq <= best_sq) {
        best_sq = d_sq;
        best = &track;
      }
    }
    if (best == nullptr) {
      if (!tracks_.push_back(Track{})) {
        ++counters_.observations_dropped;
        continue;
      }
      ++counters_.tracks_started;
      best = &tracks_.back();
      best->first_frame = frame.frame;
    }
    Track& track = *best;
    if (track.count == UINT16_MAX) continue;  // a marking seen for hours: enough
    track.sum_x += double(obs.weight) * obs.x;
    track.sum_y += double(obs.weight) * obs.y;
    track.sum_weight += obs.weight;
    ++track.count;
    track.last_frame = frame.frame;
    track.t_last = frame.t;
    track.odometer_last = odometer;
    track.has_pose = frame.has_pose;
    track.car = frame.pose;
    track.updated = true;
    if (frame.has_pose) add_drift(track, frame, obs);

    Vote* vote = nullptr;
    for (Vote& v : track.votes)
      if (v.label == obs.label) vote = &v;
    // More distinct labels than vote slots: the extras cannot win anyway.
    if (vote == nullptr && track.votes.push_back(Vote{obs.label, 0})) vote = &track.votes.back();
    if (vote == nullptr) continue;
    ++vote->count;
    if (obs.facing == Facing::kAlong) ++vote->along;
    if (obs.facing == Facing::kAgainst) ++vote->against;
  }
}

Facing LandmarkTracker::facing_of(const Vote& winner) {
  if (winner.along == winner.against) return Facing::kAny;
  return winner.along > winner.against ? Facing::kAlong : Facing::kAgainst;
}

void LandmarkTracker::add_drift(Track& track, const FrameInput& frame, const Observation& obs) {
  if (track.drift.count == 0) {
    track.car_first_x = frame.pose.x;
    track.car_first_y = frame.pose.y;
  }
  track.drift.add(frame.pose.x - track.car_first_x, frame.pose.y - track.car_first_y,
                  obs.x - track.car_first_x, obs.y - track.car_first_y, obs.weight);
}

double LandmarkTracker::station(const Track& track, double x, double y) {
  // Along-track station of the marking itself: where the car was when it
  // last saw it, plus how far ahead of the car it lies. This does not
  // depend on which frame happened to see it last.
  const double ahead =
      (x - track.car.x) * std::cos(track.car.yaw) + (y - track.car.y) * std::sin(track.car.yaw);
  return track.odometer_last + ahead;
}

double LandmarkTracker::lowest_active_station() const {
  double lowest = std::numeric_limits<double>::infinity();
  for (const Track& track : tracks_)
    if (track.has_pose)
      lowest =
          std::min(lowest, station(track, track.sum_x / track.sum_weight, track.sum_y / track.sum_weight));
  return lowest;
}

bool LandmarkTracker::to_landmark(const Track& track, Landmark& out) {
  if (track.count < config_.min_observations) {
    ++counters_.tracks_spurious;
    return false;
  }
  const Vote* winner = nullptr;
  for (const Vote& vote : track.votes)
    if (winner == nullptr || vote.count > winner->count) winner = &vote;
  if (winner == nullptr || 2u * winner->count < track.count) {
    ++counters_.tracks_label_ambiguous;
    return false;
  }
  out = Landmark{};
  out.label = winner->label;
  out.observations = track.count;
  out.first_frame = track.first_frame;
  out.last_frame = track.last_frame;
  out.x = static_cast<float>(track.sum_x / track.sum_weight);
  out.y = static_cast<float>(track.sum_y / track.sum_weight);
  out.t = track.t_last;
  out.has_car_pose = track.has_pose;
  out.facing = facing_of(*winner);
  if (track.has_pose) {
    out.car_x = static_cast<float>(track.car.x);
    out.car_y = static_cast<float>(track.car.y);
    out.car_yaw = static_cast<float>(track.car.yaw);
    out.station = station(track, out.x, out.y);
  }
  ++counters_.landmarks_committed;
  return true;
}

}  // namespace markloop
