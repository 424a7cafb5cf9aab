// What the detector's stages hand each other: parts of paint, candidates
// (groups of parts, as classified) and detections, with the box arithmetic
// and the union-find they share.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>

#include "app/engine/types.hpp"
#include "app/perception/marking_features.hpp"

namespace markloop::perception {

struct Detection {
  Label label;                               // index into kMarkingClassNames
  float score;                               // classifier confidence 0..1
  std::array<std::array<float, 2>, 4> quad;  // corners in the original image, pixels
  float ground_x, ground_y;                  // centre on the road, vehicle frame, metres
  // detect_still() only: cut by the view's near edge; quad and centre are the
  // visible part's.
  bool partial;
  // Read turned half way round: painted for the opposite direction, seen
  // from behind (a marking that a half turn leaves alike never is).
  bool turned;
};
inline constexpr std::size_t kMaxDetections = 32;

// One connected region of paint (PartLabeller). Boxes here and below are in
// bird's-eye pixels: columns left to right, rows far to near, inclusive.
struct Part {
  int col0, row0, col1, row1;
  int area;
  int group;
  bool thin;  // as thin as a line along its own axis (a dash's piece, seen at any angle)
};

// A part's principal axis on the ground: the length and width of the bar
// with the same second moments, its angle from the road's direction.
struct PartAxis {
  double mean_row, mean_col;
  double length_m, width_m;
  double angle_rad;
};

// One group of bright parts, as classified (exposed for training and tests).
struct Candidate {
  int col0, row0, col1, row1;  // inclusive
  int parts;
  float length_m, width_m;  // along and across the road
  bool clipped;             // touches the edge of the view: seen only in part
  bool clipped_near_only;   // ... and only its near edge, where the car drives on
  Features features;
  int predicted;  // class index, kRejectClass for "not a marking"
  float score;
  bool turned;  // read turned half way round: painted for the other direction
  // Index of the candidate across a letter stroke to its right
  // (DetectorConfig::stroke_min_shared), reported with this one when both
  // get the same class; -1 none.
  int across_stroke;
};
inline constexpr std::size_t kMaxCandidates = 64;
inline constexpr std::size_t kMaxParts = 1024;
inline constexpr std::size_t kMaxStrokes = 64;  // line parts short enough to be a letter

// Rows a box (part, stroke, candidate) spans, and rows two boxes share (0
// or less when they share none).
template <typename Box>
int rows_of(const Box& box) {
  return box.row1 - box.row0 + 1;
}
template <typename BoxA, typename BoxB>
int rows_shared(const BoxA& a, const BoxB& b) {
  return std::min(a.row1, b.row1) - std::max(a.row0, b.row0) + 1;
}
// The same across: columns spanned, and shared.
template <typename Box>
int cols_of(const Box& box) {
  return box.col1 - box.col0 + 1;
}
template <typename BoxA, typename BoxB>
int cols_shared(const BoxA& a, const BoxB& b) {
  return std::min(a.col1, b.col1) - std::max(a.col0, b.col0) + 1;
}

// Grows `into` to cover `from` (parts' and candidates' boxes alike).
template <typename Into, typename From>
void grow_box(Into& into, const From& from) {
  into.col0 = std::min(into.col0, from.col0);
  into.col1 = std::max(into.col1, from.col1);
  into.row0 = std::min(into.row0, from.row0);
  into.row1 = std::max(into.row1, from.row1);
}

// Union-find over indices into `parent` (parent[i] == i: a root).
inline int find_root(std::int32_t* parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];  // path halving
    i = parent[i];
  }
  return i;
}

// The smaller root becomes the root of both.
inline void unite(std::int32_t* parent, int a, int b) {
  a = find_root(parent, a);
  b = find_root(parent, b);
  if (a < b)
    parent[b] = a;
  else if (b < a)
    parent[a] = b;
}

}  // namespace markloop::perception
