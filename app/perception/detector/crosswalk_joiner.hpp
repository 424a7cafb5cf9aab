// Side-crosswalk joining, after classification: a side street's crosswalk,
// seen from the side as the car crosses the intersection, shows its
// stripes as bars across the road one behind the other, and each alone is
// classified as a stop line. A stack of such bars, evenly spaced, is
// reported as the one crosswalk it is, so both visits of a place name it
// alike and a car turning in over it names it so too.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "app/perception/birdseye.hpp"
#include "app/perception/detector/candidate.hpp"
#include "app/perception/detector/detector_config.hpp"
#include "app/perception/detector/view_edges.hpp"

namespace markloop::perception {

class CrosswalkJoiner {
 public:
  // `edges` is the detector's, kept up to date as the view moves.
  CrosswalkJoiner(const SideCrosswalkConfig& config, float bar_max_length_m, const BirdsEyeRegion& region,
                  const ViewEdges& edges);

  // Of the candidates reported alone (reported_by[i] == i), stop-line bars
  // (at most bar_max_length_m along) sharing side_crosswalk_min_shared of
  // the narrower one's columns, at least side_crosswalk_min_bars of them
  // one behind the other at a pitch within side_crosswalk_pitch_m and
  // within side_crosswalk_pitch_tolerance of the first pitch: the farthest
  // becomes a crosswalk that reports the others. A stack whose next bar
  // either way would lie where the view does not reach may go on unseen:
  // it is marked cut by the view's edge (clipped), its centre a guess.
  // Returns how many joined another's detection; nothing with the rule off.
  std::size_t join(std::span<Candidate> candidates, std::span<std::int32_t> reported_by) const;

 private:
  // The stack that starts at bar `first` of `bars` (candidate indexes
  // sorted far to near), passing over those `taken`; returns its length,
  // its members' positions in `bars` in `stack`.
  std::size_t stack_from(std::span<const Candidate> candidates, std::span<const int> bars,
                         std::span<const bool> taken, std::size_t first, std::span<int> stack) const;
  // True when the view sees all of `bar`'s box moved `rows` along.
  bool seen_moved(const Candidate& bar, int rows) const;

  SideCrosswalkConfig config_;
  const ViewEdges& edges_;
  int bar_max_rows_;
  float metres_per_row_;
};

}  // namespace markloop::perception
