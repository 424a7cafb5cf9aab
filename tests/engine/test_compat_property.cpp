// The indexed --compat matcher against the straight port of the authors'
// program on random inputs: the same matches in the same order, always.
// Inputs are built to hit the edges: few labels, coordinates on a coarse grid
// so that distances differ by exactly the tolerance or land on bin edges,
// repeated drives with small shifts, duplicate, negative and unordered
// frames, and odd parameters (zero, infinite and negative tolerances, frame
// gaps of 0 and below, far-out coordinates whose distances overflow).
#include <catch2/catch_test_macros.hpp>

#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "app/tools/replay/compat.hpp"

using namespace markloop::replay;

namespace {

using Rng = std::mt19937_64;

int uniform(Rng& rng, int lo, int hi) {
  return std::uniform_int_distribution<int>(lo, hi)(rng);
}

CompatParameters random_parameters(Rng& rng) {
  static const float kTolerances[] = {
      0.0f, 0.25f, 0.5f, 1.0f, 1.0f, 2.0f, 2.0f, 3.0f, 0.1f, -1.0f, std::numeric_limits<float>::infinity()};
  static const int kGaps[] = {-1, 0, 1, 1, 2, 2, 3, 5};
  CompatParameters p;
  p.k = static_cast<unsigned>(uniform(rng, 2, 6));
  p.frame_gap = kGaps[uniform(rng, 0, 7)];
  p.distance_tolerance = uniform(rng, 0, 4) == 0 ? std::uniform_real_distribution<float>(0.0f, 3.0f)(rng)
                                                 : kTolerances[uniform(rng, 0, 10)];
  return p;
}

// A short route of records on a grid of `unit` metres, then driven again
// several times, each later drive at least the match gap later, its
// coordinates shifted by half units now and then and a label changed rarely.
std::vector<MarkingRecord> random_records(Rng& rng, const CompatParameters& p) {
  static const char* const kLabels[] = {"A", "B", "C"};
  const int labels = uniform(rng, 1, 3);
  static const float kUnits[] = {0.5f, 1.0f, 2.0f, 0.3f, 1e18f, 1e30f};
  const float unit = kUnits[uniform(rng, 0, 2) == 0 ? uniform(rng, 0, 5) : uniform(rng, 0, 2)];
  const int step = std::max(p.frame_gap, 1);
  std::vector<MarkingRecord> route;
  int frame = uniform(rng, -60, 20);
  for (int i = uniform(rng, 1, 30); i > 0; --i) {
    frame += uniform(rng, 0, 2 * step);  // 0: several markings in one frame
    route.push_back({frame, unit * float(uniform(rng, 0, 6)), unit * float(uniform(rng, 0, 1)),
                     unit * float(uniform(rng, 0, 6)), kLabels[uniform(rng, 0, labels - 1)], 0});
  }
  std::vector<MarkingRecord> records;
  int offset = 0;
  for (int drive = uniform(rng, 1, 6); drive > 0; --drive) {
    for (MarkingRecord r : route) {
      r.frame += offset;
      if (uniform(rng, 0, 3) == 0) r.x += unit * 0.5f * float(uniform(rng, -1, 1));
      if (uniform(rng, 0, 3) == 0) r.z += unit * 0.5f * float(uniform(rng, -1, 1));
      if (uniform(rng, 0, 20) == 0) r.label = kLabels[uniform(rng, 0, 2)];
      if (uniform(rng, 0, 10) > 0) records.push_back(r);  // a marking missed now and then
    }
    offset += route.back().frame - route.front().frame + 100 * step + uniform(rng, -2 * step, 3 * step);
  }
  if (uniform(rng, 0, 5) == 0 && records.size() > 2)  // records out of frame order
    std::swap(records[std::size_t(uniform(rng, 0, int(records.size()) - 1))], records.back());
  return records;
}

}  // namespace

TEST_CASE("compat: the indexed matcher equals the all-pairs one on random inputs", "[compat]") {
  Rng rng(20260602);
  constexpr int kCases = 20000;
  std::size_t matches = 0, with_matches = 0;
  for (int i = 0; i < kCases; ++i) {
    const CompatParameters p = random_parameters(rng);
    const std::vector<MarkingRecord> records = random_records(rng, p);
    const CompatMatches indexed = run_compat(records, p);
    const CompatMatches reference = run_compat_reference(records, p);
    INFO("case " << i << ": " << records.size() << " records, k " << p.k << ", T " << p.frame_gap
                 << ", tolerance " << p.distance_tolerance << "; indexed " << indexed.size()
                 << " matches, reference " << reference.size());
    REQUIRE(indexed == reference);
    matches += reference.size();
    with_matches += !reference.empty();
  }
  // The inputs do exercise the matching (not only empty results agreeing).
  CHECK(with_matches > kCases / 4);
  CHECK(matches > 10 * kCases);
}
