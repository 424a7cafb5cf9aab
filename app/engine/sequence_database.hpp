// Bounded database of landmarks and sequences of k landmarks.
//
// Landmarks are also indexed by label and ground cell (a hash of the cell's
// chains, newest first), so that places can be found by position.
//
// Storage is allocated once, in the constructor; nothing grows afterwards.
// Both stores are rings: when full, the oldest entry is evicted. Sequences are
// indexed by an open-addressing hash table (linear probing, backward-shift
// deletion, so no tombstones) keyed on the label tuple and the quantised
// successive distances. Every bucket holds a doubly linked chain of the
// sequences sharing its key, newest first; the oldest sequence is always a
// chain tail, so eviction is O(1) and keeps the index exact.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>

#include "app/common/large_array.hpp"
#include "app/engine/config.hpp"
#include "app/engine/types.hpp"

namespace markloop {

// Labels and successive distances of a sequence; distances[0] is unused (0).
struct SequenceShape {
  unsigned k = 0;
  std::array<Label, kMaxSequenceLength> labels{};
  std::array<float, kMaxSequenceLength> distances{};
};

struct DatabaseStats {
  std::size_t landmarks = 0;
  std::size_t sequences = 0;
  std::size_t landmark_capacity = 0;
  std::size_t sequence_capacity = 0;
  std::size_t index_slots = 0;
  std::size_t index_used = 0;
  std::size_t bytes_landmarks = 0;
  std::size_t bytes_sequences = 0;  // sequence records and index together
  std::uint64_t landmarks_evicted = 0;
  std::uint64_t sequences_evicted = 0;
};

// Distance between two landmarks on the ground, metres.
float planar_distance(const Landmark& a, const Landmark& b);

// Tolerance and index quantisation shared by insertion and queries.
//
// Bins grow with distance like the tolerance does: a distance is mapped by
// g(d) ~ log2(1 + rel d / abs) / (rel log2 e), about one unit per tolerance,
// and binned in steps of `index_bin_tolerances`. The logarithm is the bit
// pattern of a positive float read as an integer: exactly monotone (which is
// all that correctness needs, since a query probes the bins of the exact
// bounds of its tolerance interval) and a few instructions instead of log1p.
// Its slope is within [ln 2, 2 ln 2] of the true one, so with bins of at
// least 3 tolerances a tolerance interval (at most 2.11 tolerances wide for
// rel <= 0.1) spans at most 2 bins: at most 2^(k-1) probes per query.
class DistanceQuantiser {
 public:
  explicit DistanceQuantiser(const MatchConfig& config);
  std::uint32_t bin(double distance) const;
  // Bins that may hold a distance within tolerance of `distance`.
  void bin_range(double distance, std::uint32_t& first, std::uint32_t& last) const;
  bool within_tolerance(double a, double b) const;
  double tolerance(double a, double b) const;

 private:
  double abs_m_;
  double rel_;
  float growth_;          // rel / abs
  double units_per_bin_;  // g units (float ulps or metres) per bin
};

class SequenceDatabase {
 public:
  // Capacities are rounded up to powers of two.
  SequenceDatabase(const DatabaseConfig& config, const MatchConfig& match, unsigned k);

  // Bytes the constructor allocates for `config` and `k`, so that a caller
  // can refuse a size the machine cannot hold before asking for it.
  // In 64 bits: on a 32-bit target the product may exceed its address space.
  static std::uint64_t bytes_needed(const DatabaseConfig& config, unsigned k);

  SequenceDatabase(const SequenceDatabase&) = delete;
  SequenceDatabase& operator=(const SequenceDatabase&) = delete;

  unsigned k() const { return k_; }

  // Stores a landmark under a fresh id, evicting the oldest one (and the
  // sequences that start at or before it) when full.
  LandmarkId add_landmark(const Landmark& landmark);
  // nullptr when the id was never stored or has been evicted.
  const Landmark* landmark(LandmarkId id) const;
  // Gives the stored landmark of `passed.id` the frame, time, car pose and
  // facing of `passed` (its position, label and station stay: the index
  // holds them). False when it has been evicted.
  bool set_frame(const Landmark& passed);

  // Calls visit(const Landmark&) for live landmarks of `label` whose position
  // lies within `radius_m` of (x, y), newest first within each ground cell;
  // at most `per_cell` landmarks of each cell are examined, so that a road
  // driven a thousand times costs no more than one driven a few times.
  template <typename Visitor>
  void for_each_landmark_near(Label label, double x, double y, double radius_m, unsigned per_cell,
                              Visitor&& visit) const;

  // Stores a sequence of k live landmark ids; returns false (and stores
  // nothing) when an id is not live.
  bool add_sequence(std::span<const LandmarkId> ids);
  // The same with the shape already computed by shape_of(ids), as the engine
  // has it from querying the sequence first.
  void add_sequence(std::span<const LandmarkId> ids, const SequenceShape& shape);

  // Shape of the sequence made of these landmark ids; false if one is not live.
  bool shape_of(std::span<const LandmarkId> ids, SequenceShape& shape) const;

  // Calls visit(std::span<const LandmarkId>) for stored sequences whose labels
  // equal the query's and whose distances are all within tolerance, at most
  // `limit` of them; visit returns false to stop. Returns how many were seen;
  // sets `limited` when the limit cut the search short.
  template <typename Visitor>
  unsigned for_each_match(const SequenceShape& query, unsigned limit, bool& limited, Visitor&& visit) const;

  DatabaseStats stats() const;
  const DistanceQuantiser& quantiser() const { return quantiser_; }

  // Live landmark ids are [first_landmark_id(), next_landmark_id()).
  LandmarkId first_landmark_id() const { return oldest_landmark_id_; }
  LandmarkId next_landmark_id() const { return next_landmark_id_; }
  // Calls visit(std::span<const LandmarkId>) for every stored sequence whose
  // landmarks are all live, oldest first (saving a map).
  template <typename Visitor>
  void for_each_sequence(Visitor&& visit) const {
    for (std::uint64_t n = oldest_sequence_; n < sequences_added_; ++n) {
      const auto seq = static_cast<std::uint32_t>(n & sequence_mask_);
      if (sequence_live(seq)) visit(std::span<const LandmarkId>(&sequence_ids_[std::size_t{seq} * k_], k_));
    }
  }

  // Drops everything (ids keep counting up, so old ids stay invalid).
  void clear();

 private:
  static constexpr std::uint32_t kNone = 0xFFFFFFFFu;
  // Each distance spans at most two bins (see validate()).
  static constexpr unsigned kMaxProbes = 1u << (kMaxSequenceLength - 1);
  static void prefetch(const void* address) {
#if defined(__GNUC__)
    __builtin_prefetch(address);
#else
    (void)address;
#endif
  }
  struct Slot {
    std::uint32_t tag = 0;
    std::uint32_t head = kNone;  // newest sequence in the chain
  };

  // Side of the ground cells of the landmark index, metres.
  static constexpr double kCell_m = 64.0;
  static std::int64_t cell_of(double coordinate) {
    return static_cast<std::int64_t>(std::floor(coordinate / kCell_m));
  }
  std::size_t cell_slot(Label label, std::int64_t cx, std::int64_t cy) const;

  std::uint64_t label_hash(const SequenceShape& shape) const;
  static std::uint32_t key_tag(std::uint64_t label_hash, std::span<const std::uint32_t> bins);
  std::uint32_t find_slot(std::uint32_t tag) const;
  void remove_slot(std::uint32_t slot);
  void evict_oldest_sequence();
  // The next insertion will evict the oldest sequence: start loading its
  // index slot now so that miss overlaps other work.
  void prefetch_eviction() const;
  bool sequence_live(std::uint32_t seq) const;
  bool shape_matches(const SequenceShape& query, std::uint32_t seq) const;

  unsigned k_;
  DistanceQuantiser quantiser_;

  LargeArray<Landmark> landmarks_;
  std::size_t landmark_mask_;
  LandmarkId next_landmark_id_ = 0;
  LandmarkId oldest_landmark_id_ = 0;

  // Landmark index: per slot (label and cell, hashed) the newest landmark;
  // per landmark the next older one of its slot. A chain ends at an id no
  // longer live: eviction is oldest first, so all behind it are gone too.
  LargeArray<LandmarkId> cell_head_;
  std::size_t cell_mask_;
  LargeArray<LandmarkId> cell_older_;  // indexed like landmarks_

  LargeArray<LandmarkId> sequence_ids_;  // k per sequence
  LargeArray<std::uint32_t> sequence_tag_;
  LargeArray<std::uint32_t> sequence_older_;  // toward the chain tail
  LargeArray<std::uint32_t> sequence_newer_;  // toward the chain head
  std::size_t sequence_mask_;
  std::uint64_t sequences_added_ = 0;
  std::uint64_t oldest_sequence_ = 0;

  LargeArray<Slot> slots_;
  std::uint32_t slot_mask_;
  std::size_t slots_used_ = 0;

  std::uint64_t landmarks_evicted_ = 0;
  std::uint64_t sequences_evicted_ = 0;
};

template <typename Visitor>
void SequenceDatabase::for_each_landmark_near(Label label, double x, double y, double radius_m,
                                              unsigned per_cell, Visitor&& visit) const {
  if (!(radius_m >= 0.0) || !std::isfinite(x) || !std::isfinite(y)) return;
  const std::int64_t x0 = cell_of(x - radius_m), x1 = cell_of(x + radius_m);
  const std::int64_t y0 = cell_of(y - radius_m), y1 = cell_of(y + radius_m);
  const double radius_sq = radius_m * radius_m;
  for (std::int64_t cx = x0; cx <= x1; ++cx) {
    for (std::int64_t cy = y0; cy <= y1; ++cy) {
      unsigned examined = 0;
      for (LandmarkId id = cell_head_[cell_slot(label, cx, cy)]; examined < per_cell; ++examined) {
        const Landmark* l = landmark(id);
        if (l == nullptr) break;
        const double dx = l->x - x, dy = l->y - y;
        // Other labels and cells share a slot now and then.
        if (l->label == label && cell_of(l->x) == cx && cell_of(l->y) == cy && dx * dx + dy * dy <= radius_sq)
          visit(*l);
        id = cell_older_[id & landmark_mask_];
      }
    }
  }
}

template <typename Visitor>
unsigned SequenceDatabase::for_each_match(const SequenceShape& query, unsigned limit, bool& limited,
                                          Visitor&& visit) const {
  limited = false;
  if (query.k != k_) return 0;
  // Each distance may fall into one or two bins; probe their product.
  std::array<std::uint32_t, kMaxSequenceLength> first{}, last{}, bins{};
  for (unsigned i = 1; i < k_; ++i) {
    quantiser_.bin_range(query.distances[i], first[i], last[i]);
    bins[i] = first[i];
  }
  // Every probe's tag first, with its slot prefetched, so the cache misses
  // of independent probes overlap instead of queueing one after another.
  std::array<std::uint32_t, kMaxProbes> tags;
  unsigned probes = 0;
  const std::span<const std::uint32_t> key_bins(bins.data() + 1, k_ - 1);
  const std::uint64_t labels = label_hash(query);
  for (;;) {
    const std::uint32_t tag = key_tag(labels, key_bins);
    tags[probes++] = tag;
    prefetch(&slots_[tag & slot_mask_]);
    unsigned i = 1;
    while (i < k_ && bins[i] == last[i]) {
      bins[i] = first[i];
      ++i;
    }
    if (i >= k_ || probes == kMaxProbes) break;
    ++bins[i];
  }

  prefetch_eviction();  // a query is usually followed by an insertion

  unsigned seen = 0;
  for (unsigned p = 0; p < probes; ++p) {
    const std::uint32_t slot = find_slot(tags[p]);
    if (slot == kNone) continue;
    for (std::uint32_t seq = slots_[slot].head; seq != kNone; seq = sequence_older_[seq]) {
      if (!shape_matches(query, seq)) continue;
      if (seen == limit) {
        limited = true;
        return seen;
      }
      ++seen;
      if (!visit(std::span<const LandmarkId>(&sequence_ids_[std::size_t{seq} * k_], k_))) return seen;
    }
  }
  return seen;
}

}  // namespace markloop
