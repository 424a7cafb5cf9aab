#include "app/tools/replay/compat.hpp"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <numeric>
#include <string>
#include <string_view>
#include <unordered_map>

namespace markloop::replay {

namespace {

// Computed in float, term by term, like the original; one function for both
// implementations, so that they agree to the bit.
float distance(float last_x, float last_y, float last_z, const MarkingRecord& r) {
  const float dx = (r.x - last_x) * (r.x - last_x);
  const float dy = (r.y - last_y) * (r.y - last_y);
  const float dz = (r.z - last_z) * (r.z - last_z);
  return std::sqrt(dx + dy + dz);
}

// Progress is reported every this many records, and every this many
// sequences searched.
constexpr std::size_t kReportEvery = 4096;

void report_now_and_then(const CompatProgressReport& report, const CompatProgress& progress,
                         std::size_t done) {
  if (report && done % kReportEvery == 0) report(progress);
}

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

}  // namespace

bool CompatMatches::operator==(const CompatMatches& other) const {
  if (size() != other.size()) return false;
  for (std::size_t i = 0; i < size(); ++i)
    if (!std::ranges::equal(earlier(i), other.earlier(i)) || !std::ranges::equal(later(i), other.later(i)))
      return false;
  return true;
}

std::uint32_t CompatMatches::add_sequence(const int* frames) {
  frames_.insert(frames_.end(), frames, frames + k_);
  return static_cast<std::uint32_t>(frames_.size() / k_ - 1);
}

CompatMatches run_compat_reference(const std::vector<MarkingRecord>& records, const CompatParameters& p) {
  std::vector<CompatSequence> sequences;
  for (const MarkingRecord& r : records) {
    if (sequences.empty()) sequences.push_back(start_sequence(r));
    bool appended_to_last = false;
    const std::size_t count = sequences.size();
    for (std::size_t j = 0; j < count; ++j) {
      CompatSequence& s = sequences[j];
      if (s.frames.size() >= p.k || std::abs(r.frame - s.frames.back()) < p.frame_gap) continue;
      s.distances.push_back(distance(s.last_x, s.last_y, s.last_z, r));
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

  CompatMatches matches(p.k);
  std::vector<std::uint32_t> ids(sequences.size());
  for (std::size_t i = 0; i < sequences.size(); ++i)
    if (sequences[i].frames.size() == p.k) ids[i] = matches.add_sequence(sequences[i].frames.data());
  for (std::size_t i = 0; i < sequences.size(); ++i) {
    const CompatSequence& a = sequences[i];
    if (a.frames.size() != p.k) continue;
    for (std::size_t j = i + 1; j < sequences.size(); ++j) {
      const CompatSequence& b = sequences[j];
      if (b.frames.size() != p.k) continue;
      bool match = true;
      for (unsigned e = 0; e < p.k && match; ++e) {
        match = *a.labels[e] == *b.labels[e] && std::abs(a.frames[e] - b.frames[e]) >= p.match_frame_gap() &&
                std::abs(a.distances[e] - b.distances[e]) <= p.distance_tolerance;
      }
      if (match) matches.add(ids[i], ids[j]);
    }
  }
  return matches;
}

namespace {

// Label names as small numbers: equal numbers for equal names.
class LabelIds {
 public:
  std::uint32_t of(const std::string& name) {
    return ids_.try_emplace(name, static_cast<std::uint32_t>(ids_.size())).first->second;
  }

 private:
  std::unordered_map<std::string_view, std::uint32_t> ids_;  // views into the records
};

// Every sequence in flat arrays, k slots each, with its last position while
// it can still grow.
class SequenceStore {
 public:
  explicit SequenceStore(unsigned k) : k_(k), stride_(std::max(k, 1u)) {}

  std::size_t count() const { return sizes_.size(); }
  bool full(std::size_t s) const { return sizes_[s] >= k_; }
  bool complete(std::size_t s) const { return sizes_[s] == k_; }
  int last_frame(std::size_t s) const { return frames_[s * stride_ + sizes_[s] - 1]; }
  const int* frames(std::size_t s) const { return &frames_[s * stride_]; }
  const std::uint32_t* labels(std::size_t s) const { return &labels_[s * stride_]; }
  const float* distances(std::size_t s) const { return &distances_[s * stride_]; }

  void start(const MarkingRecord& r, std::uint32_t label) {
    sizes_.push_back(0);
    frames_.resize(frames_.size() + stride_);
    labels_.resize(labels_.size() + stride_);
    distances_.resize(distances_.size() + stride_);
    last_.emplace_back();
    put(count() - 1, r, label, 0.0f);
  }
  void append(std::size_t s, const MarkingRecord& r, std::uint32_t label) {
    put(s, r, label, distance(last_[s].x, last_[s].y, last_[s].z, r));
  }

 private:
  struct Position {
    float x = 0, y = 0, z = 0;
  };
  void put(std::size_t s, const MarkingRecord& r, std::uint32_t label, float d) {
    const std::size_t slot = s * stride_ + sizes_[s]++;
    frames_[slot] = r.frame;
    labels_[slot] = label;
    distances_[slot] = d;
    last_[s] = {r.x, r.y, r.z};
  }

  unsigned k_, stride_;
  std::vector<unsigned> sizes_;
  std::vector<int> frames_;
  std::vector<std::uint32_t> labels_;
  std::vector<float> distances_;
  std::vector<Position> last_;
};

// The authors' rule: a record joins every sequence short of k elements whose
// last element lies at least T frames away, and starts a new sequence when it
// joined the newest one. A full sequence never changes again, so only the
// open ones are scanned, in creation order as in the original.
SequenceStore make_sequences(const std::vector<MarkingRecord>& records, const CompatParameters& p,
                             CompatProgress& progress, const CompatProgressReport& report) {
  SequenceStore store(p.k);
  LabelIds labels;
  std::vector<std::size_t> open;
  const auto start = [&](const MarkingRecord& r, std::uint32_t label) {
    store.start(r, label);
    if (!store.full(store.count() - 1)) open.push_back(store.count() - 1);
  };
  for (const MarkingRecord& r : records) {
    const std::uint32_t label = labels.of(r.label);
    if (store.count() == 0) start(r, label);
    const std::size_t newest = store.count() - 1;
    bool joined_newest = false;
    std::size_t kept = 0;
    for (std::size_t i = 0; i < open.size(); ++i) {
      const std::size_t s = open[i];
      if (std::abs(std::int64_t{r.frame} - store.last_frame(s)) >= p.frame_gap) {
        store.append(s, r, label);
        joined_newest = joined_newest || s == newest;
      }
      if (!store.full(s)) open[kept++] = s;
    }
    open.resize(kept);
    if (joined_newest) start(r, label);
    progress.sequences = store.count();
    report_now_and_then(report, progress, ++progress.records_read);
  }
  return store;
}

// Distances quantised into bins a little wider than the tolerance, so that
// two distances within the tolerance (as float arithmetic decides it) lie in
// the same or neighbouring bins, whatever the rounding of either step.
class DistanceBins {
 public:
  explicit DistanceBins(float tolerance) {
    const double widened = tolerance > 0 ? double(tolerance) * (1 + std::ldexp(1.0, -10)) : 0.0;
    width_ = std::max(widened, double(FLT_MIN));
  }
  std::int64_t of(float d) const {
    if (std::isinf(width_)) return 0;  // every distance is within an infinite tolerance
    const double bin = double(d) / width_;
    if (bin < kLargestBin) return static_cast<std::int64_t>(std::floor(bin));
    // So far out, neighbouring floats lie wider apart than the tolerance:
    // only equal distances match, and the bin is the value's bit pattern
    // (infinity and NaN included, which match nothing).
    std::uint32_t bits = 0;
    std::memcpy(&bits, &d, sizeof bits);
    return static_cast<std::int64_t>(kLargestBin) + bits;
  }

 private:
  static constexpr double kLargestBin = 0x1p40;
  double width_ = 1;
};

// The complete sequences sorted by a key of 2k - 1 dimensions: the first
// label, then each further element's label and distance bin. Sequences that
// can match share the labels and lie in neighbouring bins, so their ranges
// are found by descending the sorted keys one dimension at a time.
class MatchIndex {
 public:
  MatchIndex(const SequenceStore& store, const CompatParameters& p);
  std::size_t size() const { return members_.size(); }
  std::size_t sequence(std::size_t c) const { return members_[c]; }
  // The complete sequences after c (in creation order) that match it, ascending.
  void later_matches(std::size_t c, std::vector<std::size_t>& out) const;

 private:
  std::int64_t key(std::size_t c, unsigned d) const { return keys_[c * dims_ + d]; }
  bool is_bin(unsigned d) const { return d > 0 && d % 2 == 0; }
  void descend(std::size_t c, unsigned d, std::size_t lo, std::size_t hi,
               std::vector<std::size_t>& out) const;
  bool matches(std::size_t a, std::size_t b) const;

  const SequenceStore& store_;
  const CompatParameters p_;
  unsigned dims_;
  std::vector<std::size_t> members_;  // the complete sequences, in creation order
  std::vector<std::int64_t> keys_;    // dims_ per member
  std::vector<std::size_t> order_;    // members by key, then by creation
};

MatchIndex::MatchIndex(const SequenceStore& store, const CompatParameters& p)
    : store_(store), p_(p), dims_(p.k == 0 ? 0 : 2 * p.k - 1) {
  for (std::size_t s = 0; s < store.count(); ++s)
    if (store.complete(s)) members_.push_back(s);
  const DistanceBins bins(p.distance_tolerance);
  keys_.resize(members_.size() * dims_);
  for (std::size_t c = 0; c < members_.size(); ++c) {
    std::int64_t* key = &keys_[c * dims_];
    const std::uint32_t* labels = store.labels(members_[c]);
    const float* distances = store.distances(members_[c]);
    key[0] = labels[0];  // the first distance is always 0
    for (unsigned e = 1; e < p.k; ++e) {
      key[2 * e - 1] = labels[e];
      key[2 * e] = bins.of(distances[e]);
    }
  }
  order_.resize(members_.size());
  std::iota(order_.begin(), order_.end(), std::size_t{0});
  std::stable_sort(order_.begin(), order_.end(), [&](std::size_t a, std::size_t b) {
    return std::lexicographical_compare(&keys_[a * dims_], &keys_[(a + 1) * dims_], &keys_[b * dims_],
                                        &keys_[(b + 1) * dims_]);
  });
}

void MatchIndex::later_matches(std::size_t c, std::vector<std::size_t>& out) const {
  if (dims_ > 0) descend(c, 0, 0, order_.size(), out);
  std::sort(out.begin(), out.end());
}

// Within [lo, hi) the first d dimensions are fixed, so dimension d is sorted:
// each value c's match may take (its label, or its bin and the two beside
// it) is one sub-range. At the last dimension the range is one bucket, in
// creation order.
void MatchIndex::descend(std::size_t c, unsigned d, std::size_t lo, std::size_t hi,
                         std::vector<std::size_t>& out) const {
  const auto first = order_.begin() + static_cast<std::ptrdiff_t>(lo);
  const auto last = order_.begin() + static_cast<std::ptrdiff_t>(hi);
  if (d == dims_) {
    const auto later = std::upper_bound(first, last, c);
    for (auto it = later; it != last; ++it)
      if (matches(c, *it)) out.push_back(*it);
    return;
  }
  const std::int64_t own = key(c, d);
  const std::int64_t spread = is_bin(d) ? 1 : 0;
  for (std::int64_t value = own - spread; value <= own + spread; ++value) {
    const auto from =
        std::lower_bound(first, last, value, [&](std::size_t m, std::int64_t v) { return key(m, d) < v; });
    const auto to =
        std::upper_bound(from, last, value, [&](std::int64_t v, std::size_t m) { return v < key(m, d); });
    if (from != to)
      descend(c, d + 1, static_cast<std::size_t>(from - order_.begin()),
              static_cast<std::size_t>(to - order_.begin()), out);
  }
}

// The original's test, element by element.
bool MatchIndex::matches(std::size_t a, std::size_t b) const {
  const std::size_t sa = members_[a], sb = members_[b];
  const int* fa = store_.frames(sa);
  const int* fb = store_.frames(sb);
  const std::uint32_t* la = store_.labels(sa);
  const std::uint32_t* lb = store_.labels(sb);
  const float* da = store_.distances(sa);
  const float* db = store_.distances(sb);
  for (unsigned e = 0; e < p_.k; ++e) {
    if (la[e] != lb[e] || std::abs(std::int64_t{fa[e]} - fb[e]) < p_.match_frame_gap() ||
        !(std::abs(da[e] - db[e]) <= p_.distance_tolerance))
      return false;
  }
  return true;
}

}  // namespace

CompatMatches run_compat(const std::vector<MarkingRecord>& records, const CompatParameters& p,
                         const CompatProgressReport& report) {
  CompatProgress progress;
  progress.records = records.size();
  const SequenceStore store = make_sequences(records, p, progress, report);
  const MatchIndex index(store, p);
  progress.complete = index.size();

  CompatMatches matches(p.k);
  for (std::size_t c = 0; c < index.size(); ++c)
    matches.add_sequence(store.frames(index.sequence(c)));  // numbered c
  std::vector<std::size_t> later;
  for (std::size_t c = 0; c < index.size(); ++c) {
    later.clear();
    index.later_matches(c, later);
    for (const std::size_t m : later)
      matches.add(static_cast<std::uint32_t>(c), static_cast<std::uint32_t>(m));
    progress.matches = matches.size();
    report_now_and_then(report, progress, ++progress.searched);
  }
  if (report) report(progress);
  return matches;
}

}  // namespace markloop::replay
