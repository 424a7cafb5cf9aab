// Fuses the per-frame observations of one physical marking into a landmark
// (its position: the observations' mean, weighted by their precision).
//
// An observation joins the nearest active track within the association
// radius that has not been updated in this frame (so markings side by side in
// one frame stay separate); the label is decided by vote. A track unseen for
// `commit_after_s` has left view and is committed, unless it is spurious (too
// few observations) or its vote has no majority. Every track that leaves
// view also tells the odometry's scale (odometry_scale.hpp).
#pragma once

#include <cstdint>
#include <span>

#include "app/common/fixed_vector.hpp"
#include "app/engine/config.hpp"
#include "app/engine/odometry_scale.hpp"
#include "app/engine/types.hpp"

namespace markloop {

struct TrackerCounters {
  std::uint64_t observations = 0;
  std::uint64_t observations_rejected = 0;  // non-finite position or weight <= 0
  std::uint64_t observations_dropped = 0;   // no free track
  std::uint64_t tracks_started = 0;
  std::uint64_t landmarks_committed = 0;
  std::uint64_t tracks_spurious = 0;
  std::uint64_t tracks_label_ambiguous = 0;
};

class LandmarkTracker {
 public:
  static constexpr std::size_t kMaxTracks = 64;
  static constexpr std::size_t kMaxVotes = 4;

  explicit LandmarkTracker(const TrackerConfig& config) : config_(config) {}

  // `odometer` is the distance travelled so far, meaningful when the frame
  // has a pose.
  void observe(const FrameInput& frame, double odometer, std::span<const Observation> observations);

  // Moves landmarks whose tracks left view (or every track, when `all`) into
  // `out`, oldest sighting first. Returns false if `out` ran out of room; the
  // remaining tracks are then committed on a later call.
  template <std::size_t N>
  bool commit(double now, bool all, FixedVector<Landmark, N>& out);

  std::size_t active() const { return tracks_.size(); }
  // The lowest station an active track's landmark would have if committed
  // now; infinity when no track has a pose.
  double lowest_active_station() const;
  const TrackerCounters& counters() const { return counters_; }
  // Over the whole run: a cleared map leaves the car's odometry as it was.
  const OdometryScaleEstimator& odometry_scale() const { return scale_; }
  void clear() { tracks_.clear(); }

 private:
  struct Vote {
    Label label;
    std::uint16_t count;
    std::uint16_t along = 0;  // of them, read with a facing (Observation::facing)
    std::uint16_t against = 0;
  };
  struct Track {
    double sum_x = 0.0;  // weighted sums of the observed positions
    double sum_y = 0.0;
    double sum_weight = 0.0;
    std::uint16_t count = 0;
    FrameIndex first_frame = 0;
    FrameIndex last_frame = 0;
    double t_last = 0.0;
    double odometer_last = 0.0;
    bool has_pose = false;
    Pose2 car{};
    bool updated = false;
    FixedVector<Vote, kMaxVotes> votes;
    // The marking's world position against the car's displacement, both
    // from where the car was at the first sighting.
    MarkingFit drift;
    double car_first_x = 0.0;
    double car_first_y = 0.0;
  };

  static void add_drift(Track& track, const FrameInput& frame, const Observation& obs);
  static double station(const Track& track, double x, double y);

  bool to_landmark(const Track& track, Landmark& out);
  // The facing most of the winning label's readings gave; none on a tie.
  static Facing facing_of(const Vote& winner);

  TrackerConfig config_;
  FixedVector<Track, kMaxTracks> tracks_;
  TrackerCounters counters_;
  OdometryScaleEstimator scale_;
};

template <std::size_t N>
bool LandmarkTracker::commit(double now, bool all, FixedVector<Landmark, N>& out) {
  for (;;) {
    // Oldest sighting first, so landmarks leave in a stable order.
    std::size_t oldest = tracks_.size();
    for (std::size_t i = 0; i < tracks_.size(); ++i) {
      if (!all && now - tracks_[i].t_last <= config_.commit_after_s) continue;
      if (oldest == tracks_.size() || tracks_[i].t_last < tracks_[oldest].t_last) oldest = i;
    }
    if (oldest == tracks_.size()) return true;
    if (out.full()) return false;
    Landmark landmark;
    if (to_landmark(tracks_[oldest], landmark)) out.push_back(landmark);
    scale_.add_marking(tracks_[oldest].drift);
    tracks_.erase_at(oldest);
  }
}

}  // namespace markloop
