// The authors' published batch program, reproduced rule for rule (same
// matches, same order), for comparison with the online engine.
#pragma once

#include <vector>

#include "replay/paper_format.hpp"

namespace markloop::replay {

struct CompatMatch {
  std::vector<int> earlier;  // frame indices of the earlier sequence
  std::vector<int> later;
};

struct CompatParameters {
  unsigned k = 4;
  int frame_gap = 30;         // T: successive elements at least T frames apart
  float distance_tolerance = 2.0f;
  // Matched elements at least this many frames apart (the authors' 100 * T).
  int match_frame_gap() const { return 100 * frame_gap; }
};

// O(N^2 k); single-precision positions and distances as in the original.
std::vector<CompatMatch> run_compat(const std::vector<MarkingRecord>& records,
                                    const CompatParameters& parameters);

}  // namespace markloop::replay
