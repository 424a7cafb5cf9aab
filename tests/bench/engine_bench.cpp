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
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "app/common/cli.hpp"
#include "app/engine/place_matcher.hpp"
#include "app/engine/rigid_alignment.hpp"
#include "app/engine/sequence_database.hpp"
#include "app/engine/sequence_engine.hpp"

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
    l.station = along_;
    l.t = along_ / 10.0;
    l.has_car_pose = true;
    return l;
  }
  double along() const { return along_; }

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
  Percentiles place;
  Percentiles place_of_two;
};

// A database of one size, filled from a landmark stream, next to the naive
// matcher holding the same sequences.
class Bench {
 public:
  explicit Bench(std::size_t size) : db_(config(size), mc_, kK), size_(size) {
    naive_.tolerance = static_cast<float>(mc_.distance_tolerance_abs_m);
    naive_.entries.reserve(size);
  }

  void fill() {
    SequenceShape shape;
    std::size_t stored = 0;
    while (stored < size_) {
      if (!add_next(shape)) continue;
      db_.add_sequence(ids_);
      naive_.entries.push_back(NaiveMatcher::Entry::of(shape));
      ++stored;
    }
  }

  // A new sequence: query (with rigid verification of every candidate), then
  // insert. Half of the queries revisit a stored place, shifted by 0.1 m.
  void sample(std::size_t samples, std::size_t naive_samples) {
    std::mt19937_64 pick(7);
    indexed_ns_.reserve(samples);
    SequenceShape shape;
    for (std::size_t s = 0; s < samples; ++s) {
      while (!add_next(shape)) {
      }
      if (s % 2 == 1) revisit(naive_.entries[pick() % naive_.entries.size()], shape);
      const auto start = Clock::now();
      query(shape);
      db_.add_sequence(ids_);
      indexed_ns_.push_back(std::chrono::duration<double, std::nano>(Clock::now() - start).count());
      if (s < naive_samples) time_naive(shape, s);
      if (s % 2 == 1) time_place(pick);
      if (s % 2 == 1) time_place_of_two(pick);
    }
    if (sink_ == 0) std::fprintf(stderr, "(no candidate verified)\n");
  }

  Row row(std::size_t samples) {
    const DatabaseStats stats = db_.stats();
    Row row;
    row.size = size_;
    row.indexed = percentiles(indexed_ns_);
    row.naive = percentiles(naive_ns_);
    row.bytes_per_sequence = double(stats.bytes_sequences) / double(stats.sequence_capacity);
    row.bytes_per_landmark = double(stats.bytes_landmarks) / double(stats.landmark_capacity);
    row.candidates_per_query = double(candidates_) / double(samples);
    row.place = percentiles(place_ns_);
    row.place_of_two = percentiles(place_of_two_ns_);
    return row;
  }

 private:
  static DatabaseConfig config(std::size_t size) {
    DatabaseConfig dc;
    dc.sequence_capacity = size;
    dc.landmark_capacity = size;
    return dc;
  }

  // The next landmark into the database; true with the shape of the last
  // kK landmarks once there are as many.
  bool add_next(SequenceShape& shape) {
    recent_.push_back(db_.add_landmark(stream_.next()));
    if (recent_.size() > kK) recent_.erase(recent_.begin());
    if (recent_.size() < kK) return false;
    std::copy(recent_.begin(), recent_.end(), ids_.begin());
    return db_.shape_of(ids_, shape);
  }

  static void revisit(const NaiveMatcher::Entry& e, SequenceShape& shape) {
    std::copy_n(e.labels.begin(), kK, shape.labels.begin());
    for (unsigned i = 1; i < kK; ++i) shape.distances[i] = e.distances[i] + 0.1f;
  }

  void query(const SequenceShape& shape) {
    bool limited = false;
    db_.for_each_match(shape, mc_.max_candidates_per_query, limited, [&](std::span<const LandmarkId> match) {
      std::array<Eigen::Vector2d, kK> from, to;
      for (unsigned i = 0; i < kK; ++i) {
        const Landmark* a = db_.landmark(match[i]);
        const Landmark* b = db_.landmark(ids_[i]);
        from[i] = {a->x, a->y};
        to[i] = {b->x, b->y};
      }
      sink_ += fit_rigid_2d(from, to).rms_residual < mc_.max_residual_m;
      ++candidates_;
      return true;
    });
  }

  // A place query where four stored landmarks are seen again, 0.1 m off:
  // the newest one's neighbours, their partners, the fit and the rival check.
  void time_place(std::mt19937_64& pick) {
    const LandmarkId at = pick_landmark(pick);
    PlaceMatcher places(place_config());
    const double later = stream_.along() + 1000.0;
    for (LandmarkId id = at - kK + 1; id <= at; ++id) places.remember(seen_again(id, later));
    time_match(places, place_ns_);
  }

  // A place of two: two stored landmarks seen again, 0.1 m off, by a car
  // that drove 60 m towards them along their road, so that every stored
  // landmark it looked at is checked as well.
  void time_place_of_two(std::mt19937_64& pick) {
    const LandmarkId at = pick_landmark(pick);
    LandmarkId before = at - 1;
    while (before > db_.first_landmark_id() && db_.landmark(before)->x == db_.landmark(at)->x) --before;
    MatchConfig mc = place_config();
    mc.place_pair_min_bits = 1.0;
    PlaceMatcher places(mc);
    const double later = stream_.along() + 1000.0;
    const double newest_x = db_.landmark(at)->x;
    for (double x = newest_x - 60.0; x <= newest_x + 14.0; x += 0.5)
      places.remember_pose({x + 0.1, 0.0, 0.0}, x + later);
    for (const LandmarkId id : {before, at}) places.remember(seen_again(id, later));
    time_match(places, place_of_two_ns_);
  }

  // A stored landmark with kK stored before it and after it.
  LandmarkId pick_landmark(std::mt19937_64& pick) const {
    const LandmarkId first = db_.first_landmark_id(), next = db_.next_landmark_id();
    return first + kK + static_cast<LandmarkId>(pick() % (next - first - 2 * kK));
  }

  // Stored landmark `id` seen again `later` metres (and seconds at 10 m/s)
  // on, 0.1 m off.
  Landmark seen_again(LandmarkId id, double later) const {
    Landmark seen = *db_.landmark(id);
    seen.x += 0.1f;
    seen.station += later;
    seen.t += later / 10.0;
    return seen;
  }

  void time_match(PlaceMatcher& places, std::vector<double>& ns) {
    MatchEvent event;
    const auto start = Clock::now();
    sink_ += places.match(db_, event);
    ns.push_back(std::chrono::duration<double, std::nano>(Clock::now() - start).count());
  }

  MatchConfig place_config() const {
    MatchConfig mc = mc_;
    mc.place_landmarks = 3;
    mc.place_within_m = 1e12;  // the stream never comes back: every place is far back
    mc.max_drift_rel = 0.02;
    return mc;
  }

  void time_naive(const SequenceShape& shape, std::size_t s) {
    const auto naive_start = Clock::now();
    sink_ += naive_.match(shape);
    naive_.entries[s % size_] = NaiveMatcher::Entry::of(shape);  // fixed size, like the database
    naive_ns_.push_back(std::chrono::duration<double, std::nano>(Clock::now() - naive_start).count());
  }

  MatchConfig mc_;
  SequenceDatabase db_;
  std::size_t size_;
  NaiveMatcher naive_;
  LandmarkStream stream_{42};
  std::vector<LandmarkId> recent_;
  std::array<LandmarkId, kK> ids_{};
  std::vector<double> indexed_ns_, naive_ns_, place_ns_, place_of_two_ns_;
  std::size_t candidates_ = 0;
  std::size_t sink_ = 0;
};

Row measure(std::size_t size, std::size_t samples, std::size_t naive_samples) {
  Bench bench(size);
  bench.fill();
  bench.sample(samples, naive_samples);
  return bench.row(samples);
}

constexpr const char* kUsage =
    "usage: markloop-bench [--max N]\n\n"
    "Times a new sequence of k=4 landmarks (query, rigid verification of the\n"
    "candidates, insert) in the indexed ring-buffer database at 10^3 .. N stored\n"
    "sequences (default 10^6), next to a naive all-pairs matcher like the paper's,\n"
    "and reports memory per stored sequence and landmark; and a place query\n"
    "(PlaceMatcher: four landmarks seen again, at 3 agreeing) and a place of two\n"
    "(two seen again, every stored landmark on the car's way in checked as\n"
    "well) against the same database. Run on an idle machine.\n";

constexpr markloop::cli::OptionSpec kOptions[] = {
    {"--max", "N", "the largest database, in sequences (at least 1000)"},
};

}  // namespace

int main(int argc, char** argv) {
  cli::program_name() = "markloop-bench";
  const cli::ParsedArgs args = cli::parse_args_or_fail(argc, argv, kOptions);
  std::size_t largest = 1000000;
  for (const cli::ParsedArgs::Given& given : args.given()) {
    largest = std::strtoull(std::string(given.value).c_str(), nullptr, 10);
    if (largest < 1000) cli::fail("--max must be at least 1000");
  }
  if (args.help()) {
    std::fputs(kUsage, stdout);
    return cli::kExitOk;
  }
  std::printf("k = %u; per new sequence; indexed = this engine's database, naive = all-pairs scan\n\n", kK);
  std::printf(
      "| sequences | indexed median | indexed p99 | naive median | naive p99 | candidates/query | "
      "bytes/sequence | bytes/landmark | place median | place p99 | place of two median | place of two p99 "
      "|\n");
  std::printf("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (std::size_t size = 1000; size <= largest; size *= 10) {
    const std::size_t naive_samples = std::max<std::size_t>(50, 20000000 / size);
    const Row r = measure(size, 20000, std::min<std::size_t>(naive_samples, 20000));
    std::printf(
        "| %zu | %.0f ns | %.0f ns | %.1f us | %.1f us | %.2f | %.1f | %.1f | %.0f ns | %.0f ns | %.0f ns | "
        "%.0f ns "
        "|\n",
        r.size, r.indexed.median_ns, r.indexed.p99_ns, r.naive.median_ns / 1000.0, r.naive.p99_ns / 1000.0,
        r.candidates_per_query, r.bytes_per_sequence, r.bytes_per_landmark, r.place.median_ns, r.place.p99_ns,
        r.place_of_two.median_ns, r.place_of_two.p99_ns);
    std::fflush(stdout);
  }
  return cli::kExitOk;
}
