#include <catch2/catch_test_macros.hpp>

#include <algorithm>
#include <random>
#include <set>
#include <vector>

#include "app/engine/sequence_database.hpp"

using namespace markloop;

namespace {

Landmark at(double x, double y, Label label) {
  Landmark l;
  l.x = static_cast<float>(x);
  l.y = static_cast<float>(y);
  l.label = label;
  return l;
}

std::vector<std::vector<LandmarkId>> matches_of(const SequenceDatabase& db, const SequenceShape& shape) {
  std::vector<std::vector<LandmarkId>> found;
  bool limited = false;
  db.for_each_match(shape, 1u << 30, limited, [&](std::span<const LandmarkId> ids) {
    found.emplace_back(ids.begin(), ids.end());
    return true;
  });
  CHECK_FALSE(limited);
  return found;
}

}  // namespace

TEST_CASE("distance tolerance is absolute plus relative", "[database]") {
  MatchConfig config;
  config.distance_tolerance_abs_m = 0.5;
  config.distance_tolerance_rel = 0.02;
  const DistanceQuantiser q(config);
  CHECK(q.within_tolerance(10.0, 10.6));        // 0.6 <= 0.5 + 0.2120
  CHECK_FALSE(q.within_tolerance(10.0, 10.8));  // 0.8 > 0.716
  CHECK(q.within_tolerance(100.0, 102.4));      // 2.4 <= 2.548
  CHECK_FALSE(q.within_tolerance(100.0, 102.6));
}

TEST_CASE("every distance within tolerance falls in at most two probed bins", "[database]") {
  for (const double rel : {0.0, 0.02, 0.1}) {
    for (const double abs_m : {0.05, 0.5, 2.0}) {
      INFO("rel " << rel << " abs " << abs_m);
      MatchConfig config;
      config.distance_tolerance_abs_m = abs_m;
      config.distance_tolerance_rel = rel;
      config.index_bin_tolerances = 3.0;  // the narrowest allowed: the hardest case
      const DistanceQuantiser q(config);
      std::mt19937 rng(5);
      std::uniform_real_distribution<double> distance(0.0, 2000.0), unit(-1.0, 1.0);
      for (int i = 0; i < 100000; ++i) {
        const double d = i % 2 ? distance(rng) : distance(rng) / 100.0;
        const double other = std::max(0.0, d + unit(rng) * q.tolerance(d, d) * 1.2);
        std::uint32_t first = 0, last = 0;
        q.bin_range(d, first, last);
        REQUIRE(last - first <= 1);
        if (!q.within_tolerance(d, other)) continue;
        const std::uint32_t b = q.bin(other);
        REQUIRE(b >= first);
        REQUIRE(b <= last);
      }
    }
  }
}

TEST_CASE("a stored sequence is found by labels and distances", "[database]") {
  DatabaseConfig dc{64, 64};
  MatchConfig mc;
  SequenceDatabase db(dc, mc, 3);
  const LandmarkId a = db.add_landmark(at(0, 0, 1));
  const LandmarkId b = db.add_landmark(at(10, 0, 2));
  const LandmarkId c = db.add_landmark(at(30, 0, 3));
  const std::vector<LandmarkId> ids{a, b, c};
  REQUIRE(db.add_sequence(ids));

  SequenceShape query;
  query.k = 3;
  query.labels = {1, 2, 3};
  query.distances = {0.0f, 10.3f, 19.8f};
  CHECK(matches_of(db, query) == std::vector<std::vector<LandmarkId>>{ids});

  query.distances[1] = 11.0f;  // 1.0 m off: beyond 0.5 + 2% of 11
  CHECK(matches_of(db, query).empty());
  query.distances[1] = 10.0f;
  query.labels[2] = 4;
  CHECK(matches_of(db, query).empty());
}

TEST_CASE("a sequence of evicted landmarks is not stored", "[database]") {
  SequenceDatabase db(DatabaseConfig{16, 16}, MatchConfig{}, 2);
  const LandmarkId first = db.add_landmark(at(0, 0, 1));
  for (int i = 0; i < 16; ++i) db.add_landmark(at(i, 0, 1));
  CHECK(db.landmark(first) == nullptr);
  const LandmarkId live = db.add_landmark(at(50, 0, 1));
  const std::vector<LandmarkId> ids{first, live};
  CHECK_FALSE(db.add_sequence(ids));
}

// The index against a brute-force model: after every insertion (and the
// evictions it causes), a query finds exactly the live sequences a linear
// scan finds.
TEST_CASE("eviction keeps the index exact", "[database]") {
  const unsigned k = 3;
  DatabaseConfig dc{64, 32};
  MatchConfig mc;
  SequenceDatabase db(dc, mc, k);
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> label(0, 2);  // few labels: long chains
  std::uniform_int_distribution<int> step(0, 3);

  std::vector<LandmarkId> recent;
  std::vector<std::vector<LandmarkId>> stored;  // every sequence ever added
  double x = 0;
  for (int round = 0; round < 3000; ++round) {
    x += 5.0 * (1 + step(rng));  // distances on a coarse grid: many collide
    recent.push_back(db.add_landmark(at(x, 0, static_cast<Label>(label(rng)))));
    if (recent.size() < k) continue;
    std::vector<LandmarkId> ids(recent.end() - k, recent.end());
    REQUIRE(db.add_sequence(ids));
    stored.push_back(ids);

    const DatabaseStats stats = db.stats();
    REQUIRE(stats.sequences <= stats.sequence_capacity);
    REQUIRE(stats.landmarks <= stats.landmark_capacity);
    if (round % 7 != 0) continue;

    SequenceShape query;
    REQUIRE(db.shape_of(ids, query));
    std::set<std::vector<LandmarkId>> expected;
    const std::size_t live = std::min<std::size_t>(stats.sequences, stored.size());
    for (std::size_t i = stored.size() - live; i < stored.size(); ++i) {
      SequenceShape shape;
      if (!db.shape_of(stored[i], shape)) continue;
      bool same = shape.labels == query.labels;
      for (unsigned j = 1; j < k && same; ++j)
        same = db.quantiser().within_tolerance(shape.distances[j], query.distances[j]);
      if (same) expected.insert(stored[i]);
    }
    const auto found = matches_of(db, query);
    const std::set<std::vector<LandmarkId>> found_set(found.begin(), found.end());
    REQUIRE(found.size() == found_set.size());
    REQUIRE(found_set == expected);
  }
  const DatabaseStats stats = db.stats();
  CHECK(stats.sequences_evicted > 0);
  CHECK(stats.landmarks_evicted > 0);
  // Every live sequence has exactly one chain, so slots in use never exceed it.
  CHECK(stats.index_used <= stats.sequences);
}

TEST_CASE("clearing empties the index", "[database]") {
  SequenceDatabase db(DatabaseConfig{64, 64}, MatchConfig{}, 2);
  const LandmarkId a = db.add_landmark(at(0, 0, 1));
  const LandmarkId b = db.add_landmark(at(10, 0, 2));
  const std::vector<LandmarkId> ids{a, b};
  REQUIRE(db.add_sequence(ids));
  db.clear();
  CHECK(db.stats().sequences == 0);
  CHECK(db.stats().index_used == 0);
  CHECK(db.landmark(a) == nullptr);
}
