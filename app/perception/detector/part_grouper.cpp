#include "app/perception/detector/part_grouper.hpp"

#include <algorithm>
#include <cmath>

namespace markloop::perception {
namespace {

int pixels(float metres, float step_m) {
  return static_cast<int>(std::lround(metres / step_m));
}

}  // namespace

PartGrouper::PartGrouper(const GroupingConfig& config, const PartConfig& parts, const BirdsEyeRegion& region,
                         const PaintMask& paint, const ViewEdges& edges)
    : config_(config),
      max_length_m_(parts.max_marking_length_m),
      max_width_m_(parts.max_marking_width_m),
      x_step_m_(region.x_step_m),
      y_step_m_(region.y_step_m),
      paint_(paint),
      edges_(edges) {
  const float xs = region.x_step_m, ys = region.y_step_m;
  px_.gap_cols = pixels(config.group_gap_across_m, ys);
  px_.gap_rows = pixels(config.group_gap_along_m, xs);
  px_.max_cols = pixels(config.group_max_part_m, ys);
  px_.max_rows = pixels(config.group_max_part_m, xs);
  px_.bar_min_cols = pixels(config.bar_min_width_m, ys);
  px_.bar_max_rows = pixels(config.bar_max_length_m, xs);
  px_.line_cols = pixels(parts.line_max_width_m, ys);
  px_.stripe_gap_cols = pixels(config.stripe_gap_across_m, ys);
  px_.stripe_min_rows = pixels(config.stripe_min_length_m, xs);
  px_.stripe_max_cols = pixels(config.stripe_max_width_m, ys);
  group_parent_.assign(kMaxParts, 0);
  part_groupable_.assign(kMaxParts, 0);
  group_candidate_.assign(kMaxParts, -1);
}

std::size_t PartGrouper::group(std::span<const Part> parts, std::span<const Part> strokes,
                               std::span<Candidate> candidates, DetectorCounters& counters) {
  unite_parts(parts);
  const std::size_t grouped = collect_candidates(parts, candidates, counters);
  const std::size_t kept = keep_marking_sized(candidates, grouped, counters);
  counters.candidates += kept;
  link_across_strokes(strokes, candidates.first(kept));
  return kept;
}

std::uint8_t PartGrouper::groupable(const Part& p) const {
  const bool bar = cols_of(p) >= px_.bar_min_cols && rows_of(p) <= px_.bar_max_rows;
  // A thin part running out of the view (a lane dash coming into sight,
  // too short yet to be set apart as a line; on a bend at an angle) would
  // make a marking it joins look cut by the edge.
  const bool line_coming_in = (cols_of(p) <= px_.line_cols || p.thin) && (touched_edges(p) & kOtherEdge) != 0;
  if (p.col1 - p.col0 >= px_.max_cols || p.row1 - p.row0 >= px_.max_rows || bar || line_coming_in) return 0;
  // (A piece of a lane dash is as thin as a line, a stripe wider.)
  const int rows = rows_of(p), cols = cols_of(p);
  const float fill = static_cast<float>(p.area) / static_cast<float>(rows * cols);
  const bool stripe = rows >= px_.stripe_min_rows && cols > px_.line_cols && cols <= px_.stripe_max_cols &&
                      fill >= config_.stripe_min_fill;
  return stripe ? kGroupable | kStripe : kGroupable;
}

// Two stripes side by side: most of the shorter one's rows shared.
bool PartGrouper::stripes_side_by_side(const Part& a, const Part& b) const {
  if (b.col0 > a.col1 + px_.stripe_gap_cols || a.col0 > b.col1 + px_.stripe_gap_cols) return false;
  const int shared = rows_shared(a, b);
  const int shorter = std::min(rows_of(a), rows_of(b));
  return static_cast<float>(shared) >= config_.stripe_min_shared * static_cast<float>(shorter);
}

void PartGrouper::unite_parts(std::span<const Part> parts) {
  std::int32_t* parent = group_parent_.data();
  const std::size_t count = parts.size();
  // Decided once per part: the pairs below would scan a thin part's edge
  // paint once per partner.
  for (std::size_t i = 0; i < count; ++i) {
    parent[i] = static_cast<std::int32_t>(i);
    part_groupable_[i] = groupable(parts[i]);
  }
  const int gap_cols = px_.gap_cols, gap_rows = px_.gap_rows;
  for (std::size_t i = 0; i < count; ++i) {
    const Part& a = parts[i];
    if (part_groupable_[i] == 0) continue;
    for (std::size_t j = i + 1; j < count; ++j) {
      const Part& b = parts[j];
      if (part_groupable_[j] == 0) continue;
      const bool close = b.col0 <= a.col1 + gap_cols && a.col0 <= b.col1 + gap_cols &&
                         b.row0 <= a.row1 + gap_rows && a.row0 <= b.row1 + gap_rows;
      const bool stripes =
          (part_groupable_[i] & part_groupable_[j] & kStripe) != 0 && stripes_side_by_side(a, b);
      if (close || stripes) unite(parent, static_cast<int>(i), static_cast<int>(j));
    }
  }
}

std::size_t PartGrouper::collect_candidates(std::span<const Part> parts, std::span<Candidate> candidates,
                                            DetectorCounters& counters) {
  std::int32_t* parent = group_parent_.data();
  std::size_t count = 0;
  for (std::size_t i = 0; i < parts.size(); ++i) group_candidate_[i] = -1;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const int root = find_root(parent, static_cast<int>(i));
    const Part& p = parts[i];
    std::int32_t& slot = group_candidate_[root];
    if (slot >= 0) {
      Candidate& c = candidates[static_cast<std::size_t>(slot)];
      grow_box(c, p);
      ++c.parts;
      continue;
    }
    if (count == candidates.size()) {
      ++counters.candidates_dropped;
      continue;
    }
    slot = static_cast<std::int32_t>(count++);
    Candidate& c = candidates[static_cast<std::size_t>(slot)];
    c.col0 = p.col0;
    c.row0 = p.row0;
    c.col1 = p.col1;
    c.row1 = p.row1;
    c.parts = 1;
    c.across_stroke = -1;
  }
  return count;
}

std::size_t PartGrouper::keep_marking_sized(std::span<Candidate> candidates, std::size_t count,
                                            DetectorCounters& counters) {
  // Groups grown too large are not markings (the edges of cars, shadows).
  std::size_t kept = 0;
  for (std::size_t i = 0; i < count; ++i) {
    Candidate& c = candidates[i];
    c.length_m = static_cast<float>(rows_of(c)) * x_step_m_;
    c.width_m = static_cast<float>(cols_of(c)) * y_step_m_;
    if (c.length_m > max_length_m_ || c.width_m > max_width_m_) {
      ++counters.oversize;
      continue;
    }
    const std::uint8_t edges = touched_edges(c);
    c.clipped = edges != 0;
    c.clipped_near_only = edges == kNearEdge;
    candidates[kept++] = c;
  }
  return kept;
}

void PartGrouper::link_across_strokes(std::span<const Part> strokes, std::span<Candidate> candidates) const {
  for (const Part& stroke : strokes) link_across(stroke, strokes, candidates);
  spread_cuts(candidates);
}

void PartGrouper::link_across(const Part& stroke, std::span<const Part> strokes,
                              std::span<Candidate> candidates) const {
  const int gap_cols = px_.gap_cols;
  // A letter's group beside the stroke: close across, along the stroke's
  // whole length, and at most twice as long (its group may have taken in
  // paint just beyond the letters).
  const auto beside = [&](const Candidate& c) {
    const int shared = rows_shared(c, stroke);
    return static_cast<float>(shared) >= config_.stroke_min_shared * static_cast<float>(rows_of(stroke)) &&
           2 * shared >= rows_of(c);
  };
  int left = -1, right = -1;
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    const Candidate& c = candidates[i];
    if (!beside(c)) continue;
    // (A box may reach a column or two into the stroke's: letters slanted
    // in the view on a bend.)
    if (c.col0 < stroke.col0 && c.col1 <= stroke.col1 && stroke.col0 - c.col1 - 1 <= gap_cols)
      left = static_cast<int>(i);
    if (c.col1 > stroke.col1 && c.col0 >= stroke.col0 && c.col0 - stroke.col1 - 1 <= gap_cols)
      right = static_cast<int>(i);
  }
  if (left >= 0 && right >= 0) {
    candidates[static_cast<std::size_t>(left)].across_stroke = right;
    return;
  }
  if (left < 0 && right < 0) return;
  // Letters on one side only: those on the other may have run out of the
  // view, the stroke with them or as a sliver beside it (the X of XING cut
  // to its upright by the image's side).
  const int side = left >= 0 ? 1 : -1;  // towards the missing letters
  if (runs_out_of_view(stroke, side, strokes)) {
    Candidate& letters = candidates[static_cast<std::size_t>(left >= 0 ? left : right)];
    letters.clipped = true;
    letters.clipped_near_only = false;
  }
}

void PartGrouper::spread_cuts(std::span<Candidate> candidates) {
  // A word is seen whole only where all its letters are: the letters across
  // a stroke from a cut one (the X of XING run out of the image's side) are
  // cut too, else their half would be reported as the word, a metre off.
  // Cuts only spread, so this settles within one pass per link.
  bool spread = true;
  for (std::size_t pass = 0; spread && pass < candidates.size(); ++pass) {
    spread = false;
    for (std::size_t i = 0; i < candidates.size(); ++i) {
      const int j = candidates[i].across_stroke;
      if (j < 0) continue;
      Candidate& a = candidates[i];
      Candidate& b = candidates[static_cast<std::size_t>(j)];
      const bool clipped = a.clipped || b.clipped;
      const bool near_only =
          clipped && (!a.clipped || a.clipped_near_only) && (!b.clipped || b.clipped_near_only);
      for (Candidate* c : {&a, &b}) {
        if (c->clipped == clipped && c->clipped_near_only == near_only) continue;
        c->clipped = clipped;
        c->clipped_near_only = near_only;
        spread = true;
      }
    }
  }
}

bool PartGrouper::runs_out_of_view(const Part& stroke, int side, std::span<const Part> strokes) const {
  if ((touched_edges(stroke) & kOtherEdge) != 0) return true;
  const int rows = rows_of(stroke);
  for (const Part& beyond : strokes) {
    const int gap = side > 0 ? beyond.col0 - stroke.col1 - 1 : stroke.col0 - beyond.col1 - 1;
    const int shared = rows_shared(beyond, stroke);
    if (gap < 0 || gap > px_.gap_cols ||
        static_cast<float>(shared) < config_.stroke_min_shared * static_cast<float>(rows))
      continue;
    if ((touched_edges(beyond) & kOtherEdge) != 0) return true;
  }
  return false;
}

}  // namespace markloop::perception
