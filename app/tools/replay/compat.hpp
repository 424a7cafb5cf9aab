// The authors' published batch program, reproduced rule for rule (same
// matches, same order), for comparison with the online engine.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <utility>
#include <vector>

#include "app/tools/replay/paper_format.hpp"

namespace markloop::replay {

struct CompatMatch {
  std::vector<int> earlier;  // frame indices of the earlier sequence
  std::vector<int> later;
};

// The matches in order, as pairs of sequences whose frames are kept once:
// a sequence matches many others, and a match costs 8 bytes, not two lists.
class CompatMatches {
 public:
  explicit CompatMatches(unsigned k = 0) : k_(k) {}

  std::size_t size() const { return pairs_.size(); }
  bool empty() const { return pairs_.empty(); }
  std::span<const int> earlier(std::size_t i) const { return sequence(pairs_[i].first); }
  std::span<const int> later(std::size_t i) const { return sequence(pairs_[i].second); }
  CompatMatch operator[](std::size_t i) const {
    return {{earlier(i).begin(), earlier(i).end()}, {later(i).begin(), later(i).end()}};
  }
  // Equal when every match has the same frames, in the same order.
  bool operator==(const CompatMatches& other) const;

  // A sequence of k frames, numbered from 0 in the order added.
  std::uint32_t add_sequence(const int* frames);
  void add(std::uint32_t earlier, std::uint32_t later) { pairs_.emplace_back(earlier, later); }

 private:
  std::span<const int> sequence(std::uint32_t s) const { return {&frames_[std::size_t{s} * k_], k_}; }

  unsigned k_;
  std::vector<int> frames_;  // k per sequence
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs_;
};

struct CompatParameters {
  unsigned k = 4;
  int frame_gap = 30;  // T: successive elements at least T frames apart
  float distance_tolerance = 2.0f;
  // Matched elements at least this many frames apart (the authors' 100 * T).
  int match_frame_gap() const { return 100 * frame_gap; }
};

// How far a run is, for progress reports: records are read first (making
// sequences), then each complete sequence is searched for its matches.
struct CompatProgress {
  std::size_t records = 0;
  std::size_t records_read = 0;
  std::size_t sequences = 0;  // made so far
  std::size_t complete = 0;   // sequences of k elements, once all records are read
  std::size_t searched = 0;   // complete sequences searched
  std::size_t matches = 0;    // found so far
};
using CompatProgressReport = std::function<void(const CompatProgress&)>;

// The authors' matches in their order, found through an index: sequences
// bucketed by labels and quantised distances, so that only sequences that
// can match are compared. Linear in the records plus the matches on drives
// (the all-pairs cost returns only where most sequences do match). `report`,
// when set, is called now and then during the run and once at its end.
CompatMatches run_compat(const std::vector<MarkingRecord>& records, const CompatParameters& parameters,
                         const CompatProgressReport& report = {});

// The straight port: every sequence against every other, O(N^2 k);
// single-precision positions and distances as in the original. The
// reference that run_compat is tested and measured against.
CompatMatches run_compat_reference(const std::vector<MarkingRecord>& records,
                                   const CompatParameters& parameters);

}  // namespace markloop::replay
