#include "replay/compat.hpp"

#include <cmath>
#include <cstdlib>
#include <string>

namespace markloop::replay {

namespace {

struct CompatSequence {
  std::vector<int> frames;
  std::vector<const std::string*> labels;
  std::vector<float> distances;  // to the previous element; 0 for the first
  float last_x = 0, last_y = 0, last_z = 0;
};

CompatSequence start_sequence(const MarkingRecord& r) {
  CompatSequence s;
  s.frames.push_back(r.frame);
  s.labels.push_back(&r.label);
  s.distances.push_back(0.0f);
  s.last_x = r.x;
  s.last_y = r.y;
  s.last_z = r.z;
  return s;
}

// Computed in float, term by term, like the original.
float distance(const CompatSequence& s, const MarkingRecord& r) {
  const float dx = (r.x - s.last_x) * (r.x - s.last_x);
  const float dy = (r.y - s.last_y) * (r.y - s.last_y);
  const float dz = (r.z - s.last_z) * (r.z - s.last_z);
  return std::sqrt(dx + dy + dz);
}

}  // namespace

std::vector<CompatMatch> run_compat(const std::vector<MarkingRecord>& records,
                                    const CompatParameters& p) {
  std::vector<CompatSequence> sequences;
  for (const MarkingRecord& r : records) {
    if (sequences.empty()) sequences.push_back(start_sequence(r));
    bool appended_to_last = false;
    const std::size_t count = sequences.size();
    for (std::size_t j = 0; j < count; ++j) {
      CompatSequence& s = sequences[j];
      if (s.frames.size() >= p.k || std::abs(r.frame - s.frames.back()) < p.frame_gap) continue;
      s.distances.push_back(distance(s, r));
      s.frames.push_back(r.frame);
      s.labels.push_back(&r.label);
      s.last_x = r.x;
      s.last_y = r.y;
      s.last_z = r.z;
      if (j == count - 1) appended_to_last = true;
    }
    // The new one-element sequence would not take the record itself (frame
    // gap 0), so appending it after the loop is equivalent to the original.
    if (appended_to_last) sequences.push_back(start_sequence(r));
  }

  std::vector<CompatMatch> matches;
  for (std::size_t i = 0; i < sequences.size(); ++i) {
    const CompatSequence& a = sequences[i];
    if (a.frames.size() != p.k) continue;
    for (std::size_t j = i + 1; j < sequences.size(); ++j) {
      const CompatSequence& b = sequences[j];
      if (b.frames.size() != p.k) continue;
      bool match = true;
      for (unsigned e = 0; e < p.k && match; ++e) {
        match = *a.labels[e] == *b.labels[e] &&
                std::abs(a.frames[e] - b.frames[e]) >= p.match_frame_gap() &&
                std::abs(a.distances[e] - b.distances[e]) <= p.distance_tolerance;
      }
      if (match) matches.push_back({a.frames, b.frames});
    }
  }
  return matches;
}

}  // namespace markloop::replay
