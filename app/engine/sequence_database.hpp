// Bounded database of landmarks and sequences of k landmarks.
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
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "engine/config.hpp"
#include "engine/types.hpp"

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

// Tolerance and index quantisation shared by insertion and queries.
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
  double bin_width_;
};

class SequenceDatabase {
 public:
  // Capacities are rounded up to powers of two.
  SequenceDatabase(const DatabaseConfig& config, const MatchConfig& match, unsigned k);

  SequenceDatabase(const SequenceDatabase&) = delete;
  SequenceDatabase& operator=(const SequenceDatabase&) = delete;

  unsigned k() const { return k_; }

  // Stores a landmark under a fresh id, evicting the oldest one (and the
  // sequences that start at or before it) when full.
  LandmarkId add_landmark(const Landmark& landmark);
  // nullptr when the id was never stored or has been evicted.
  const Landmark* landmark(LandmarkId id) const;

  // Stores a sequence of k live landmark ids; returns false (and stores
  // nothing) when an id is not live.
  bool add_sequence(std::span<const LandmarkId> ids);

  // Shape of the sequence made of these landmark ids; false if one is not live.
  bool shape_of(std::span<const LandmarkId> ids, SequenceShape& shape) const;

  // Calls visit(std::span<const LandmarkId>) for stored sequences whose labels
  // equal the query's and whose distances are all within tolerance, at most
  // `limit` of them; visit returns false to stop. Returns how many were seen;
  // sets `limited` when the limit cut the search short.
  template <typename Visitor>
  unsigned for_each_match(const SequenceShape& query, unsigned limit, bool& limited,
                          Visitor&& visit) const;

  DatabaseStats stats() const;
  const DistanceQuantiser& quantiser() const { return quantiser_; }

  // Drops everything (ids keep counting up, so old ids stay invalid).
  void clear();

 private:
  static constexpr std::uint32_t kNone = 0xFFFFFFFFu;
  struct Slot {
    std::uint32_t tag = 0;
    std::uint32_t head = kNone;  // newest sequence in the chain
  };

  std::uint32_t key_tag(const SequenceShape& shape,
                        std::span<const std::uint32_t> bins) const;
  std::uint32_t find_slot(std::uint32_t tag) const;
  void remove_slot(std::uint32_t slot);
  void evict_oldest_sequence();
  bool sequence_live(std::uint32_t seq) const;
  bool shape_matches(const SequenceShape& query, std::uint32_t seq) const;

  unsigned k_;
  DistanceQuantiser quantiser_;

  std::vector<Landmark> landmarks_;
  std::size_t landmark_mask_;
  LandmarkId next_landmark_id_ = 0;
  LandmarkId oldest_landmark_id_ = 0;

  std::vector<LandmarkId> sequence_ids_;  // k per sequence
  std::vector<std::uint32_t> sequence_tag_;
  std::vector<std::uint32_t> sequence_older_;  // toward the chain tail
  std::vector<std::uint32_t> sequence_newer_;  // toward the chain head
  std::size_t sequence_mask_;
  std::uint64_t sequences_added_ = 0;
  std::uint64_t oldest_sequence_ = 0;

  std::vector<Slot> slots_;
  std::uint32_t slot_mask_;
  std::size_t slots_used_ = 0;

  std::uint64_t landmarks_evicted_ = 0;
  std::uint64_t sequences_evicted_ = 0;
};

template <typename Visitor>
unsigned SequenceDatabase::for_each_match(const SequenceShape& query, unsigned limit,
                                          bool& limited, Visitor&& visit) const {
  limited = false;
  if (query.k != k_) return 0;
  // Each distance may fall into one or two bins; enumerate their product.
  std::array<std::uint32_t, kMaxSequenceLength> first{}, last{}, bins{};
  for (unsigned i = 1; i < k_; ++i) {
    quantiser_.bin_range(query.distances[i], first[i], last[i]);
    bins[i] = first[i];
  }
  unsigned seen = 0;
  const std::span<const std::uint32_t> key_bins(bins.data() + 1, k_ - 1);
  for (;;) {
    const std::uint32_t slot = find_slot(key_tag(query, key_bins));
    if (slot != kNone) {
      for (std::uint32_t seq = slots_[slot].head; seq != kNone; seq = sequence_older_[seq]) {
        if (!shape_matches(query, seq)) continue;
        if (seen == limit) {
          limited = true;
          return seen;
        }
        ++seen;
        if (!visit(std::span<const LandmarkId>(&sequence_ids_[std::size_t{seq} * k_], k_)))
          return seen;
      }
    }
    // Next combination of bins (odometer order).
    unsigned i = 1;
    while (i < k_ && bins[i] == last[i]) {
      bins[i] = first[i];
      ++i;
    }
    if (i >= k_) break;
    ++bins[i];
  }
  return seen;
}

}  // namespace markloop
