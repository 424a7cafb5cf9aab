#include "app/engine/sequence_database.hpp"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <numbers>

namespace markloop {

namespace {

std::size_t power_of_two_at_least(std::size_t n) {
  return std::bit_ceil(std::max<std::size_t>(n, 2));
}

std::uint64_t mix(std::uint64_t h) {
  // splitmix64 finaliser: good avalanche, cheap, identical on every target.
  h ^= h >> 30;
  h *= 0xBF58476D1CE4E5B9ull;
  h ^= h >> 27;
  h *= 0x94D049BB133111EBull;
  h ^= h >> 31;
  return h;
}

}  // namespace

float planar_distance(const Landmark& a, const Landmark& b) {
  // Plain sqrt: hypot's overflow care costs time and road distances are small.
  const float dx = a.x - b.x;
  const float dy = a.y - b.y;
  return std::sqrt(dx * dx + dy * dy);
}

DistanceQuantiser::DistanceQuantiser(const MatchConfig& config)
    : abs_m_(config.distance_tolerance_abs_m),
      rel_(config.distance_tolerance_rel),
      growth_(static_cast<float>(rel_ / abs_m_)) {
  // One unit of log2 is 2^23 float ulps; one tolerance is rel * log2(e) of
  // log2 (relative growth), or abs_m metres without a relative part.
  units_per_bin_ =
      config.index_bin_tolerances * (rel_ > 0.0 ? rel_ * std::numbers::log2e * 8388608.0 : abs_m_);
}

std::uint32_t DistanceQuantiser::bin(double distance) const {
  const double d = std::max(distance, 0.0);
  if (rel_ <= 0.0) return static_cast<std::uint32_t>(std::min(d / units_per_bin_, 4.0e9));
  const float grown = 1.0f + growth_ * static_cast<float>(std::min(d, 1.0e9));
  const std::uint32_t ulps = std::bit_cast<std::uint32_t>(grown) - 0x3F800000u;  // bits of 1.0f
  return static_cast<std::uint32_t>(ulps / units_per_bin_);
}

void DistanceQuantiser::bin_range(double distance, std::uint32_t& first, std::uint32_t& last) const {
  // All d2 with |d - d2| <= abs + rel * max(d, d2).
  first = bin(distance * (1.0 - rel_) - abs_m_);
  last = bin((distance + abs_m_) / (1.0 - rel_));
}

double DistanceQuantiser::tolerance(double a, double b) const {
  return abs_m_ + rel_ * std::max(a, b);
}

bool DistanceQuantiser::within_tolerance(double a, double b) const {
  return std::abs(a - b) <= tolerance(a, b);
}

SequenceDatabase::SequenceDatabase(const DatabaseConfig& config, const MatchConfig& match, unsigned k)
    : k_(k), quantiser_(match) {
  assert(k >= 2 && k <= kMaxSequenceLength);
  const std::size_t landmark_capacity = power_of_two_at_least(config.landmark_capacity);
  const std::size_t sequence_capacity = power_of_two_at_least(config.sequence_capacity);
  landmarks_ = LargeArray<Landmark>(landmark_capacity);
  landmark_mask_ = landmark_capacity - 1;
  cell_head_ = LargeArray<LandmarkId>(2 * landmark_capacity);
  std::fill_n(&cell_head_[0], 2 * landmark_capacity, kNoLandmark);
  cell_mask_ = 2 * landmark_capacity - 1;
  cell_older_ = LargeArray<LandmarkId>(landmark_capacity);
  sequence_ids_ = LargeArray<LandmarkId>(sequence_capacity * k_);
  sequence_tag_ = LargeArray<std::uint32_t>(sequence_capacity);
  sequence_older_ = LargeArray<std::uint32_t>(sequence_capacity);
  sequence_newer_ = LargeArray<std::uint32_t>(sequence_capacity);
  sequence_mask_ = sequence_capacity - 1;
  // Load factor at most 1/2 keeps linear probes short.
  const std::size_t slot_count = power_of_two_at_least(2 * sequence_capacity);
  assert(slot_count <= (std::size_t{1} << 32));
  slots_ = LargeArray<Slot>(slot_count);
  slot_mask_ = static_cast<std::uint32_t>(slot_count - 1);
}

std::uint64_t SequenceDatabase::bytes_needed(const DatabaseConfig& config, unsigned k) {
  const auto power_of_two = [](std::uint64_t n) { return std::bit_ceil(std::max<std::uint64_t>(n, 2)); };
  const std::uint64_t landmarks = power_of_two(config.landmark_capacity);
  const std::uint64_t sequences = power_of_two(config.sequence_capacity);
  const std::uint64_t slots = power_of_two(2 * sequences);
  return landmarks * (sizeof(Landmark) + 3 * sizeof(LandmarkId)) +
         sequences * (k * sizeof(LandmarkId) + 3 * sizeof(std::uint32_t)) + slots * sizeof(Slot);
}

void SequenceDatabase::clear() {
  while (oldest_sequence_ < sequences_added_) evict_oldest_sequence();
  oldest_landmark_id_ = next_landmark_id_;
}

LandmarkId SequenceDatabase::add_landmark(const Landmark& landmark) {
  if (next_landmark_id_ - oldest_landmark_id_ > landmark_mask_) {
    const LandmarkId evicted = oldest_landmark_id_++;
    ++landmarks_evicted_;
    // Sequences are stored in creation order, which follows their first
    // landmark closely; a straggler whose landmark is gone is skipped by
    // sequence_live() until its own turn to be evicted.
    while (oldest_sequence_ < sequences_added_ &&
           sequence_ids_[static_cast<std::size_t>(oldest_sequence_ & sequence_mask_) * k_] <= evicted)
      evict_oldest_sequence();
  }
  const LandmarkId id = next_landmark_id_++;
  Landmark& stored = landmarks_[id & landmark_mask_];
  stored = landmark;
  stored.id = id;
  const std::size_t slot = cell_slot(landmark.label, cell_of(landmark.x), cell_of(landmark.y));
  cell_older_[id & landmark_mask_] = cell_head_[slot];
  cell_head_[slot] = id;
  return id;
}

std::size_t SequenceDatabase::cell_slot(Label label, std::int64_t cx, std::int64_t cy) const {
  const std::uint64_t h =
      mix(mix(mix(0x63656C6Cull ^ label) ^ static_cast<std::uint64_t>(cx)) ^ static_cast<std::uint64_t>(cy));
  return static_cast<std::size_t>(h) & cell_mask_;
}

const Landmark* SequenceDatabase::landmark(LandmarkId id) const {
  if (id < oldest_landmark_id_ || id >= next_landmark_id_) return nullptr;
  return &landmarks_[id & landmark_mask_];
}

bool SequenceDatabase::set_frame(const Landmark& passed) {
  if (passed.id < oldest_landmark_id_ || passed.id >= next_landmark_id_) return false;
  copy_frame(passed, landmarks_[passed.id & landmark_mask_]);
  return true;
}

bool SequenceDatabase::shape_of(std::span<const LandmarkId> ids, SequenceShape& shape) const {
  if (ids.size() != k_) return false;
  shape.k = k_;
  const Landmark* previous = nullptr;
  for (unsigned i = 0; i < k_; ++i) {
    const Landmark* current = landmark(ids[i]);
    if (current == nullptr) return false;
    shape.labels[i] = current->label;
    shape.distances[i] = previous == nullptr ? 0.0f : planar_distance(*current, *previous);
    previous = current;
  }
  return true;
}

std::uint64_t SequenceDatabase::label_hash(const SequenceShape& shape) const {
  std::uint64_t h = 0x6D61726B6C6F6F70ull;  // "markloop"
  for (unsigned i = 0; i < k_; ++i) h = mix(h ^ shape.labels[i]);
  return h;
}

std::uint32_t SequenceDatabase::key_tag(std::uint64_t label_hash, std::span<const std::uint32_t> bins) {
  std::uint64_t h = label_hash;
  for (const std::uint32_t b : bins) h = mix(h ^ (std::uint64_t{b} << 16));
  return static_cast<std::uint32_t>(h >> 32);
}

std::uint32_t SequenceDatabase::find_slot(std::uint32_t tag) const {
  for (std::uint32_t i = tag & slot_mask_;; i = (i + 1) & slot_mask_) {
    if (slots_[i].head == kNone) return kNone;
    if (slots_[i].tag == tag) return i;
  }
}

void SequenceDatabase::remove_slot(std::uint32_t hole) {
  // Backward-shift deletion: pull later entries of the probe run into the hole
  // when their home slot allows it, so lookups never need tombstones.
  for (std::uint32_t j = (hole + 1) & slot_mask_; slots_[j].head != kNone; j = (j + 1) & slot_mask_) {
    const std::uint32_t home = slots_[j].tag & slot_mask_;
    const bool movable = hole <= j ? (home <= hole || home > j) : (home <= hole && home > j);
    if (movable) {
      slots_[hole] = slots_[j];
      hole = j;
    }
  }
  slots_[hole] = Slot{};
  --slots_used_;
}

void SequenceDatabase::evict_oldest_sequence() {
  const auto seq = static_cast<std::uint32_t>(oldest_sequence_ & sequence_mask_);
  ++oldest_sequence_;
  ++sequences_evicted_;
  assert(sequence_older_[seq] == kNone);  // the oldest is always a chain tail
  const std::uint32_t newer = sequence_newer_[seq];
  if (newer != kNone) {
    sequence_older_[newer] = kNone;
    return;
  }
  const std::uint32_t slot = find_slot(sequence_tag_[seq]);
  assert(slot != kNone && slots_[slot].head == seq);
  remove_slot(slot);
}

void SequenceDatabase::prefetch_eviction() const {
  if (sequences_added_ - oldest_sequence_ <= sequence_mask_) return;
  const auto victim = static_cast<std::size_t>(oldest_sequence_ & sequence_mask_);
  prefetch(&slots_[sequence_tag_[victim] & slot_mask_]);
}

bool SequenceDatabase::add_sequence(std::span<const LandmarkId> ids) {
  SequenceShape shape;
  if (!shape_of(ids, shape)) return false;
  add_sequence(ids, shape);
  return true;
}

void SequenceDatabase::add_sequence(std::span<const LandmarkId> ids, const SequenceShape& shape) {
  prefetch_eviction();
  std::array<std::uint32_t, kMaxSequenceLength> bins{};
  for (unsigned i = 1; i < k_; ++i) bins[i - 1] = quantiser_.bin(shape.distances[i]);
  const std::uint32_t tag = key_tag(label_hash(shape), std::span<const std::uint32_t>(bins.data(), k_ - 1));

  if (sequences_added_ - oldest_sequence_ > sequence_mask_) evict_oldest_sequence();
  const auto seq = static_cast<std::uint32_t>(sequences_added_ & sequence_mask_);
  ++sequences_added_;
  std::copy(ids.begin(), ids.end(), &sequence_ids_[std::size_t{seq} * k_]);
  sequence_tag_[seq] = tag;
  sequence_newer_[seq] = kNone;

  std::uint32_t i = tag & slot_mask_;
  while (slots_[i].head != kNone && slots_[i].tag != tag) i = (i + 1) & slot_mask_;
  if (slots_[i].head == kNone) {
    slots_[i].tag = tag;
    sequence_older_[seq] = kNone;
    ++slots_used_;
  } else {
    sequence_older_[seq] = slots_[i].head;
    sequence_newer_[slots_[i].head] = seq;
  }
  slots_[i].head = seq;
}

bool SequenceDatabase::sequence_live(std::uint32_t seq) const {
  const LandmarkId* ids = &sequence_ids_[std::size_t{seq} * k_];
  for (unsigned i = 0; i < k_; ++i)
    if (ids[i] < oldest_landmark_id_) return false;
  return true;
}

bool SequenceDatabase::shape_matches(const SequenceShape& query, std::uint32_t seq) const {
  if (!sequence_live(seq)) return false;
  const LandmarkId* ids = &sequence_ids_[std::size_t{seq} * k_];
  const Landmark* previous = nullptr;
  for (unsigned i = 0; i < k_; ++i) {
    const Landmark& current = landmarks_[ids[i] & landmark_mask_];
    if (current.label != query.labels[i]) return false;
    if (previous != nullptr) {
      if (!quantiser_.within_tolerance(planar_distance(current, *previous), query.distances[i])) return false;
    }
    previous = &current;
  }
  return true;
}

DatabaseStats SequenceDatabase::stats() const {
  DatabaseStats s;
  s.landmarks = next_landmark_id_ - oldest_landmark_id_;
  s.sequences = static_cast<std::size_t>(sequences_added_ - oldest_sequence_);
  s.landmark_capacity = landmarks_.size();
  s.sequence_capacity = sequence_tag_.size();
  s.index_slots = slots_.size();
  s.index_used = slots_used_;
  s.bytes_landmarks =
      landmarks_.size() * sizeof(Landmark) + (cell_head_.size() + cell_older_.size()) * sizeof(LandmarkId);
  s.bytes_sequences = sequence_ids_.size() * sizeof(LandmarkId) +
                      sequence_tag_.size() * 3 * sizeof(std::uint32_t) + slots_.size() * sizeof(Slot);
  s.landmarks_evicted = landmarks_evicted_;
  s.sequences_evicted = sequences_evicted_;
  return s;
}

}  // namespace markloop
