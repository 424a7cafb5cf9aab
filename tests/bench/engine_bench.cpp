// markloop-bench: time per new sequence (query + verification + insert) in
// the bounded, indexed database at 10^3 .. 10^6 stored sequences, next to a
// naive all-pairs matcher like the paper's, and memory per stored entry.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "app/engine/rigid_alignment.hpp"
#include "app/engine/sequence_database.hpp"

namespace {

using namespace markloop;
using Clock = std::chrono::steady_clock;
constexpr unsigned kK = 4;

// A long drive's landmarks: rows of one or two markings every 15..60 m,
// labels drawn from a skewed class mix (arrows dominate, as on real roads).
class LandmarkStream {
 public:
  explicit LandmarkStream(std::uint64_t seed) : rng_(seed) {}
  Landmark next() {
    Landmark l;
    if (side_by_side_) {
      side_by_side_ = false;
      l.x = static_cast<float>(along_);
      l.y = 3.5f;
    } else {
      along_ += spacing_(rng_);
      side_by_side_ = coin_(rng_) < 0.4;
      l.x = static_cast<float>(along_);
      l.y = 0.0f;
    }
    l.label = static_cast<Label>(label_(rng_));
    return l;
  }

 private:
  std::mt19937_64 rng_;
  std::uniform_real_distribution<double> spacing_{15.0, 60.0};
  std::uniform_real_distribution<double> coin_{0.0, 1.0};
  std::discrete_distribution<int> label_{18, 15, 10, 5, 5, 5, 5, 5, 8, 2, 5, 10, 5, 2};
  double along_ = 0.0;
  bool side_by_side_ = false;
};

struct Percentiles {
  double median_ns, p99_ns;
};

Percentiles percentiles(std::vector<double>& samples) {
  std::sort(samples.begin(), samples.end());
  return {samples[samples.size() / 2], samples[samples.size() * 99 / 100]};
}

// The paper's matcher: every stored sequence compared with the new one.
struct NaiveMatcher {
  struct Entry {
    std::array<Label, kK> labels;
    std::array<float, kK> distances;
    static Entry of(const SequenceShape& shape) {
      Entry e;
      std::copy_n(shape.labels.begin(), kK, e.labels.begin());
      std::copy_n(shape.distances.begin(), kK, e.distances.begin());
      return e;
    }
  };
  std::vector<Entry> entries;
  float tolerance = 0.5f;
  std::size_t match(const SequenceShape& q) const {
    std::size_t found = 0;
    for (const Entry& e : entries) {
      bool same = true;
      for (unsigned i = 0; i < kK && same; ++i)
        same = e.labels[i] == q.labels[i] && std::abs(e.distances[i] - q.distances[i]) <= tolerance;
      found += same;
    }
    return found;
  }
};

struct Row {
  std::size_t size;
  Percentiles indexed;
  Percentiles naive;
  double bytes_per_sequence;
  double bytes_per_landmark;
  double candidates_per_query;
};

Row measure(std::size_t size, std::size_t samples, std::size_t naive_samples) {
  DatabaseConfig dc;
  dc.sequence_capacity = size;
  dc.landmark_capacity = size;
  MatchConfig mc;
  SequenceDatabase db(dc, mc, kK);
  NaiveMatcher naive;
  naive.tolerance = static_cast<float>(mc.distance_tolerance_abs_m);
  naive.entries.reserve(size);

  LandmarkStream stream(42);
  std::vector<LandmarkId> recent;
  std::array<LandmarkId, kK> ids{};
  const auto add_next = [&](SequenceShape& shape) {
    recent.push_back(db.add_landmark(stream.next()));
    if (recent.size() > kK) recent.erase(recent.begin());
    if (recent.size() < kK) return false;
    std::copy(recent.begin(), recent.end(), ids.begin());
    return db.shape_of(ids, shape);
  };

  SequenceShape shape;
  std::size_t stored = 0;
  while (stored < size) {
    if (!add_next(shape)) continue;
    db.add_sequence(ids);
    naive.entries.push_back(NaiveMatcher::Entry::of(shape));
    ++stored;
  }

  // A new sequence: query (with rigid verification of every candidate), then
  // insert. Half of the queries revisit a stored place, shifted by 0.1 m.
  std::mt19937_64 pick(7);
  std::vector<double> indexed_ns, naive_ns;
  indexed_ns.reserve(samples);
  std::size_t candidates = 0;
  std::size_t sink = 0;
  for (std::size_t s = 0; s < samples; ++s) {
    if (!add_next(shape)) {
      --s;
      continue;
    }
    if (s % 2 == 1) {
      const auto& e = naive.entries[pick() % naive.entries.size()];
      std::copy_n(e.labels.begin(), kK, shape.labels.begin());
      for (unsigned i = 1; i < kK; ++i) shape.distances[i] = e.distances[i] + 0.1f;
    }
    const auto start = Clock::now();
    bool limited = false;
    db.for_each_match(shape, mc.max_candidates_per_query, limited, [&](std::span<const LandmarkId> match) {
      std::array<Eigen::Vector2d, kK> from, to;
      for (unsigned i = 0; i < kK; ++i) {
        const Landmark* a = db.landmark(match[i]);
        const Landmark* b = db.landmark(ids[i]);
        from[i] = {a->x, a->y};
        to[i] = {b->x, b->y};
      }
      sink += fit_rigid_2d(from, to).rms_residual < mc.max_residual_m;
      ++candidates;
      return true;
    });
    db.add_sequence(ids);
    indexed_ns.push_back(std::chrono::duration<double, std::nano>(Clock::now() - start).count());

    if (s < naive_samples) {
      const auto naive_start = Clock::now();
      sink += naive.match(shape);
      naive.entries[s % size] = NaiveMatcher::Entry::of(shape);  // fixed size, like the database
      naive_ns.push_back(std::chrono::duration<double, std::nano>(Clock::now() - naive_start).count());
    }
  }
  if (sink == 0) std::fprintf(stderr, "(no candidate verified)\n");

  const DatabaseStats stats = db.stats();
  Row row;
  row.size = size;
  row.indexed = percentiles(indexed_ns);
  row.naive = percentiles(naive_ns);
  row.bytes_per_sequence = double(stats.bytes_sequences) / double(stats.sequence_capacity);
  row.bytes_per_landmark = double(stats.bytes_landmarks) / double(stats.landmark_capacity);
  row.candidates_per_query = double(candidates) / double(samples);
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  std::size_t largest = 1000000;
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::puts(
          "usage: markloop-bench [--max N]\n\n"
          "Times a new sequence of k=4 landmarks (query, rigid verification of the\n"
          "candidates, insert) in the indexed ring-buffer database at 10^3 .. N stored\n"
          "sequences (default 10^6), next to a naive all-pairs matcher like the paper's,\n"
          "and reports memory per stored sequence and landmark. Run on an idle machine.");
      return 0;
    }
    if (arg == "--max" && i + 1 < argc) {
      largest = std::strtoull(argv[++i], nullptr, 10);
      if (largest < 1000) {
        std::fputs("markloop-bench: --max must be at least 1000\n", stderr);
        return 2;
      }
    } else {
      std::fprintf(stderr, "markloop-bench: unknown option %s (see --help)\n", argv[i]);
      return 2;
    }
  }
  std::printf("k = %u; per new sequence; indexed = this engine's database, naive = all-pairs scan\n\n", kK);
  std::printf(
      "| sequences | indexed median | indexed p99 | naive median | naive p99 | candidates/query | "
      "bytes/sequence | bytes/landmark |\n");
  std::printf("|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (std::size_t size = 1000; size <= largest; size *= 10) {
    const std::size_t naive_samples = std::max<std::size_t>(50, 20000000 / size);
    const Row r = measure(size, 20000, std::min<std::size_t>(naive_samples, 20000));
    std::printf("| %zu | %.0f ns | %.0f ns | %.1f us | %.1f us | %.2f | %.1f | %.1f |\n", r.size,
                r.indexed.median_ns, r.indexed.p99_ns, r.naive.median_ns / 1000.0, r.naive.p99_ns / 1000.0,
                r.candidates_per_query, r.bytes_per_sequence, r.bytes_per_landmark);
    std::fflush(stdout);
  }
  return 0;
}
