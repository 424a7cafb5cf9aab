// Grouping, the detector's third stage: parts close along and across the
// road (letters of a word, digits of a number), and a crosswalk's stripes
// side by side, become one candidate; candidates either side of a letter
// set apart as a line (a stroke) are linked, to be reported as one word.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "app/perception/birdseye.hpp"
#include "app/perception/detector/candidate.hpp"
#include "app/perception/detector/detector_config.hpp"
#include "app/perception/detector/detector_counters.hpp"
#include "app/perception/detector/paint_mask.hpp"
#include "app/perception/detector/view_edges.hpp"

namespace markloop::perception {

class PartGrouper {
 public:
  // `paint` and `edges` (whose mask and edges are read) must outlive this.
  PartGrouper(const GroupingConfig& config, const PartConfig& parts, const BirdsEyeRegion& region,
              const PaintMask& paint, const ViewEdges& edges);

  // Groups `parts` into `candidates` (box, parts, size, cut by the view's
  // edge; not classified), linked across `strokes`. Returns how many.
  std::size_t group(std::span<const Part> parts, std::span<const Part> strokes,
                    std::span<Candidate> candidates, DetectorCounters& counters);

 private:
  // The grouping settings in view pixels.
  struct GroupPixels {
    int gap_cols, gap_rows;  // group_gap_across_m, group_gap_along_m
    int max_cols, max_rows;  // group_max_part_m
    int bar_min_cols, bar_max_rows;
    int line_cols;  // line_max_width_m
    int stripe_gap_cols, stripe_min_rows, stripe_max_cols;
  };
  // part_groupable_ bits: may join a group, and as a stripe.
  static constexpr std::uint8_t kGroupable = 1, kStripe = 2;

  std::uint8_t groupable(const Part& part) const;
  bool stripes_side_by_side(const Part& a, const Part& b) const;
  void unite_parts(std::span<const Part> parts);
  std::size_t collect_candidates(std::span<const Part> parts, std::span<Candidate> candidates,
                                 DetectorCounters& counters);
  // Drops groups too large to be a marking; notes which are cut by the
  // view's edge. Returns how many are kept.
  std::size_t keep_marking_sized(std::span<Candidate> candidates, std::size_t count,
                                 DetectorCounters& counters);
  // Links the candidates either side of each letter-like stroke
  // (Candidate::across_stroke), and marks as cut those across a stroke from
  // letters cut by the view's edge: the word is seen only in part.
  void link_across_strokes(std::span<const Part> strokes, std::span<Candidate> candidates) const;
  void link_across(const Part& stroke, std::span<const Part> strokes, std::span<Candidate> candidates) const;
  static void spread_cuts(std::span<Candidate> candidates);
  // True when a stroke, or one within gap_cols of it towards `side` (+1 its
  // right, -1 its left) along most of its rows, touches the view's side or
  // far edge.
  bool runs_out_of_view(const Part& stroke, int side, std::span<const Part> strokes) const;
  template <typename Box>
  std::uint8_t touched_edges(const Box& box) const {
    return edges_.touched(paint_.mask(), box);
  }

  GroupingConfig config_;
  float max_length_m_, max_width_m_;  // PartConfig::max_marking_*
  float x_step_m_, y_step_m_;
  GroupPixels px_{};
  const PaintMask& paint_;
  const ViewEdges& edges_;
  std::vector<std::int32_t> group_parent_;     // union-find over parts
  std::vector<std::uint8_t> part_groupable_;   // per part: kGroupable | kStripe
  std::vector<std::int32_t> group_candidate_;  // group root -> candidate index
};

}  // namespace markloop::perception
