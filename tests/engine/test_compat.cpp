// The authors' batch program, checked against cases worked by hand from its
// rules (frame gap T = 30, match gap 3000, distance tolerance 2 m).
#include <catch2/catch_test_macros.hpp>

#include <limits>
#include <vector>

#include "app/tools/replay/compat.hpp"

using namespace markloop::replay;

namespace {
MarkingRecord rec(int frame, float x, float y, float z, const char* label) {
  return {frame, x, y, z, label, 0};
}
// Both implementations, which must agree.
CompatMatches run(const std::vector<MarkingRecord>& records, unsigned k) {
  CompatParameters p;
  p.k = k;
  CompatMatches matches = run_compat(records, p);
  CHECK(matches == run_compat_reference(records, p));
  return matches;
}
}  // namespace

TEST_CASE("compat: empty input gives no matches", "[compat]") {
  CHECK(run({}, 4).empty());
  CHECK(run({rec(0, 0, 0, 0, "A")}, 2).empty());
}

// Worked by hand (k = 2):
//   r0 f0 A (0,0,0)     list [ [r0] ]
//   r1 f10 B            10 frames after r0 (< T): joins nothing, starts nothing
//   r2 f40 B (0,0,5)    joins [r0] -> [r0 r2] d=5; it joined the last: start [r2]
//   r3 f3100 A (0,0,100) joins [r2] -> [r2 r3]; start [r3]
//   r4 f3140 B (0,0,105.5) joins [r3] -> [r3 r4] d=5.5; start [r4]
// Complete: [0 40] A,B (0,5); [40 3100] B,A; [3100 3140] A,B (0,5.5).
// [0 40] vs [3100 3140]: labels equal, frame gaps 3100 >= 3000, |5-5.5| <= 2.
TEST_CASE("compat: sequences follow the frame-gap and last-sequence rules", "[compat]") {
  const std::vector<MarkingRecord> records{rec(0, 0, 0, 0, "A"), rec(10, 1, 0, 0, "B"), rec(40, 0, 0, 5, "B"),
                                           rec(3100, 0, 0, 100, "A"), rec(3140, 0, 0, 105.5f, "B")};
  const auto matches = run(records, 2);
  REQUIRE(matches.size() == 1);
  CHECK(matches[0].earlier == std::vector<int>{0, 40});
  CHECK(matches[0].later == std::vector<int>{3100, 3140});
}

// Boundaries: frame gap exactly 3000 and distance difference exactly 2 match.
//   r0 f0 A (0,0,0); r1 f30 B (3,0,0) -> [0 30] d=3, start [30]
//   r2 f3000 A (0,0,100) -> [30 3000], start [3000]
//   r3 f3030 B (0,0,105) -> [3000 3030] d=5, start [3030]
TEST_CASE("compat: gap 3000 and tolerance 2 m are inclusive", "[compat]") {
  std::vector<MarkingRecord> records{rec(0, 0, 0, 0, "A"), rec(30, 3, 0, 0, "B"), rec(3000, 0, 0, 100, "A"),
                                     rec(3030, 0, 0, 105, "B")};
  auto matches = run(records, 2);
  REQUIRE(matches.size() == 1);
  CHECK(matches[0].earlier == std::vector<int>{0, 30});
  CHECK(matches[0].later == std::vector<int>{3000, 3030});

  records[2].frame = 2999;  // first elements now 2999 frames apart
  CHECK(run(records, 2).empty());

  records[2].frame = 3000;
  records[3].z = 105.5f;  // |3 - 5.5| > 2
  CHECK(run(records, 2).empty());

  records[3].z = 105;
  records[3].label = std::string("C");  // (not = "C": GCC 12's false -Wrestrict, its bug 105329)
  CHECK(run(records, 2).empty());
}

// Matches come out in list order (i < j), earlier sequence first, and a
// record joins every open sequence it is far enough from.
//   k = 3: r0 f0, r1 f40 -> [0 40], [40]; r2 f80 -> [0 40 80], [40 80], [80]
TEST_CASE("compat: a record joins every open sequence", "[compat]") {
  const std::vector<MarkingRecord> first{rec(0, 0, 0, 0, "A"), rec(40, 0, 0, 10, "A"),
                                         rec(80, 0, 0, 20, "A")};
  std::vector<MarkingRecord> records = first;
  for (const MarkingRecord& r : first) {
    MarkingRecord again = r;
    again.frame += 5000;
    records.push_back(again);
  }
  // f5000 (z 0): [40 80] -> [40 80 5000] d(10,20); [80] -> [80 5000]; start [5000]
  // f5040 (z 10): [80 5000] -> [80 5000 5040] d(20,10); [5000] -> [5000 5040]; start [5040]
  // f5080 (z 20): [5000 5040] -> [5000 5040 5080] d(10,10); [5040] -> [5040 5080]; start [5080]
  // Complete: S0 [0 40 80], S1 [40 80 5000], S2 [80 5000 5040], S3 [5000 5040 5080].
  // Only S0-S3 have every frame gap >= 3000 (S1-S3 and S2-S3 fail at the
  // last positions) and equal distances.
  const auto matches = run(records, 3);
  REQUIRE(matches.size() == 1);
  CHECK(matches[0].earlier == std::vector<int>{0, 40, 80});
  CHECK(matches[0].later == std::vector<int>{5000, 5040, 5080});
}

// Progress: records read and sequences made, then complete sequences
// searched and matches found, the last report giving the totals.
TEST_CASE("compat: progress reports end with the totals", "[compat]") {
  std::vector<MarkingRecord> records;
  for (int drive = 0; drive < 3; ++drive)
    for (int i = 0; i < 1500; ++i)  // more than one report's worth
      records.push_back(rec(drive * 100000 + i * 31, 0, 0, float(i % 7), i % 3 ? "A" : "B"));
  CompatParameters p;
  std::vector<CompatProgress> reports;
  const CompatMatches matches =
      run_compat(records, p, [&](const CompatProgress& r) { reports.push_back(r); });
  REQUIRE(reports.size() >= 2);
  const CompatProgress& last = reports.back();
  CHECK(last.records == records.size());
  CHECK(last.records_read == records.size());
  CHECK(last.sequences >= last.complete);
  CHECK(last.searched == last.complete);
  CHECK(last.matches == matches.size());
  CHECK(matches.size() > 0);
  CHECK(reports.front().records_read < records.size());
}

// Distances that overflow float: infinite ones match only within an
// infinite tolerance (inf - 0 <= inf), never within a finite or NaN one.
//   k = 2: [0 30] d=inf, [30 3000] d=inf, [3000 3030] d=0; only the first
//   and the last are 3000 frames apart at both elements.
TEST_CASE("compat: infinite distances and tolerances", "[compat]") {
  const std::vector<MarkingRecord> records{rec(0, 0, 0, 0, "A"), rec(30, 1e30f, 0, 0, "A"),
                                           rec(3000, 0, 0, 0, "A"), rec(3030, 0, 0, 0, "A")};
  CompatParameters p;
  p.k = 2;
  CHECK(run_compat(records, p).empty());
  p.distance_tolerance = std::numeric_limits<float>::infinity();
  const CompatMatches matches = run_compat(records, p);
  CHECK(matches == run_compat_reference(records, p));
  REQUIRE(matches.size() == 1);
  CHECK(matches[0].earlier == std::vector<int>{0, 30});
  CHECK(matches[0].later == std::vector<int>{3000, 3030});
  p.distance_tolerance = std::numeric_limits<float>::quiet_NaN();
  CHECK(run_compat(records, p).empty());
  CHECK(run_compat_reference(records, p).empty());
}
