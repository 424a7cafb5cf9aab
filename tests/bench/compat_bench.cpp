// markloop-compat-bench: markloop-replay --compat's indexed matcher next to
// the straight port of the authors' all-pairs program, on many drives of one
// route, at several numbers of drives; the two outputs are compared whole.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "app/common/cli.hpp"
#include "app/tools/replay/compat.hpp"

namespace {

using namespace markloop::replay;
using Clock = std::chrono::steady_clock;

// One route's markings, fixed: rows of one to three side-by-side markings
// (one per lane) every 15..60 m, labels from a skewed class mix as on real roads.
struct Marking {
  double along_m, lateral_m;
  std::string label;
};

std::vector<Marking> route_markings(double length_m, std::mt19937_64& rng) {
  static const char* const kLabels[] = {"forward",      "leftturn", "rightturn", "forward&right",
                                        "forward&left", "bike",     "xing",      "ped",
                                        "stop",         "diamond",  "30",        "50"};
  std::discrete_distribution<int> label{18, 15, 10, 5, 5, 5, 8, 5, 5, 2, 5, 5};
  std::uniform_real_distribution<double> spacing(15.0, 60.0), coin(0.0, 1.0);
  std::vector<Marking> markings;
  for (double along = 30.0; along < length_m; along += spacing(rng)) {
    for (double lateral = 0; lateral < 10.0 && (lateral == 0 || coin(rng) < 0.5); lateral += 3.5)
      markings.push_back({along, lateral, kLabels[label(rng)]});
  }
  return markings;
}

// A winding road: heading as a sum of slow sines, integrated every metre.
struct Route {
  std::vector<double> x, z, heading;
  explicit Route(double length_m) {
    double px = 0, pz = 0;
    for (int s = 0; s <= static_cast<int>(length_m) + 1; ++s) {
      const double h = 0.8 * std::sin(s / 400.0) + 0.5 * std::sin(s / 1300.0);
      x.push_back(px);
      z.push_back(pz);
      heading.push_back(h);
      px += std::sin(h);
      pz += std::cos(h);
    }
  }
  // World x, z of a point `lateral_m` right of the road at `along_m`.
  void place(double along_m, double lateral_m, double& wx, double& wz) const {
    const auto i = static_cast<std::size_t>(along_m);
    wx = x[i] + std::cos(heading[i]) * lateral_m;
    wz = z[i] - std::sin(heading[i]) * lateral_m;
  }
};

// `drives` drives of one 3.7 km route at 30 frames/s, one after another in
// frame numbers: each drive at its own speed (6-14 m/s), every marking 5-25 m
// ahead detected in a frame with probability 0.28, its centroid with 0.3 m of
// noise. About 3,000 records a drive, as in the paper's dataset.
std::vector<MarkingRecord> synthetic_drives(int drives, std::uint64_t seed) {
  constexpr double kRoute_m = 3700.0, kFps = 30.0, kNear_m = 5.0, kFar_m = 25.0;
  std::mt19937_64 rng(seed);
  const Route route(kRoute_m + kFar_m);
  const std::vector<Marking> markings = route_markings(kRoute_m, rng);
  std::uniform_real_distribution<double> speed(6.0, 14.0), coin(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.3);
  std::vector<MarkingRecord> records;
  int frame = 0;
  for (int d = 0; d < drives; ++d) {
    const double step_m = speed(rng) / kFps;
    std::size_t first = 0;  // markings behind the car are done
    for (double at = 0; at < kRoute_m; at += step_m, ++frame) {
      while (first < markings.size() && markings[first].along_m < at + kNear_m) ++first;
      for (std::size_t m = first; m < markings.size() && markings[m].along_m <= at + kFar_m; ++m) {
        if (coin(rng) >= 0.28) continue;
        double wx = 0, wz = 0;
        route.place(markings[m].along_m, markings[m].lateral_m, wx, wz);
        records.push_back({frame, static_cast<float>(wx + noise(rng)), 1.5f,
                           static_cast<float>(wz + noise(rng)), markings[m].label, 0});
      }
    }
    frame += 300;  // between drives
  }
  return records;
}

double seconds_of(const auto& run) {
  const auto start = Clock::now();
  run();
  return std::chrono::duration<double>(Clock::now() - start).count();
}

struct Row {
  std::size_t records = 0, sequences = 0, complete = 0, matches = 0;
  double reference_s = -1, indexed_s = 0;
  bool same = true;
};

// The indexed matcher, median of three runs; the reference once, when its
// estimated time is within the limit.
Row measure(const std::vector<MarkingRecord>& records, double reference_estimate_s, double limit_s) {
  CompatParameters p;
  Row row;
  row.records = records.size();
  CompatMatches indexed;
  std::vector<double> times;
  for (int i = 0; i < 3; ++i) {
    times.push_back(seconds_of([&] {
      indexed = run_compat(records, p, [&](const CompatProgress& progress) {
        row.sequences = progress.sequences;
        row.complete = progress.complete;
      });
    }));
  }
  std::sort(times.begin(), times.end());
  row.indexed_s = times[1];
  row.matches = indexed.size();
  if (reference_estimate_s > limit_s) return row;
  CompatMatches reference;
  row.reference_s = seconds_of([&] { reference = run_compat_reference(records, p); });
  row.same = reference == indexed;
  return row;
}

bool write_markings(const std::string& path, const std::vector<MarkingRecord>& records) {
  FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) return false;
  std::fprintf(f, "%zu\n", records.size());
  for (const MarkingRecord& r : records)
    std::fprintf(f, "%d %.4f %.4f %.4f %s\n", r.frame, r.x, r.y, r.z, r.label.c_str());
  return std::fclose(f) == 0;
}

constexpr const char* kUsage =
    "usage: markloop-compat-bench [--drives N] [--limit S] [--write FILE]\n\n"
    "Times markloop-replay --compat's indexed matcher (run_compat, median of 3)\n"
    "and the straight port of the authors' all-pairs program (run_compat_reference,\n"
    "once) on N/8, N/4, N/2 and N synthetic drives of one 3.7 km route (default\n"
    "N = 200, about 600,000 records), k = 4, T = 30, tolerance 2 m, and checks\n"
    "that both give the same matches in the same order. The reference is skipped\n"
    "where its time, extrapolated quadratically, would pass S seconds (default\n"
    "60). --write FILE also writes the N drives in the paper's format.\n";

}  // namespace

constexpr markloop::cli::OptionSpec kOptions[] = {
    {"--drives", "N", "drives in the largest run (at least 8)"},
    {"--limit", "S", "skip the reference where it would pass S seconds"},
    {"--write", "FILE", "also write the N drives in the paper's format"},
};

int main(int argc, char** argv) {
  markloop::cli::program_name() = "markloop-compat-bench";
  const auto args = markloop::cli::parse_args_or_fail(argc, argv, kOptions);
  if (args.help()) {
    std::fputs(kUsage, stdout);
    return markloop::cli::kExitOk;
  }
  const std::string drives_text(args.value("--drives").value_or("200"));
  const std::string limit_text(args.value("--limit").value_or("60"));
  const int drives = std::atoi(drives_text.c_str());
  const double limit_s = std::atof(limit_text.c_str());
  const std::string write(args.value("--write").value_or(""));
  if (drives < 8) markloop::cli::fail("--drives must be at least 8");
  if (!write.empty() && !write_markings(write, synthetic_drives(drives, 1))) {
    std::fprintf(stderr, "markloop-compat-bench: %s: cannot write\n", write.c_str());
    return markloop::cli::kExitOutputFailed;
  }
  std::printf(
      "k = 4, T = 30 frames, tolerance 2 m; wall time; reference = all pairs, indexed = "
      "markloop-replay --compat\n\n");
  std::printf(
      "| drives | records | sequences | complete | matches | reference s | indexed s | "
      "speed-up | same output |\n");
  std::printf("|---:|---:|---:|---:|---:|---:|---:|---:|---|\n");
  double last_reference_s = 0, last_reference_records = 0;
  bool all_same = true;
  for (const int n : {drives / 8, drives / 4, drives / 2, drives}) {
    const std::vector<MarkingRecord> records = synthetic_drives(n, 1);
    const double growth = last_reference_records > 0 ? double(records.size()) / last_reference_records : 0;
    const Row r = measure(records, last_reference_s * growth * growth, limit_s);
    char reference[32] = "-", speedup[32] = "-";
    if (r.reference_s >= 0) {
      std::snprintf(reference, sizeof reference, "%.2f", r.reference_s);
      std::snprintf(speedup, sizeof speedup, "%.0fx", r.reference_s / r.indexed_s);
      last_reference_s = r.reference_s;
      last_reference_records = double(r.records);
    }
    std::printf("| %d | %zu | %zu | %zu | %zu | %s | %.3f | %s | %s |\n", n, r.records, r.sequences,
                r.complete, r.matches, reference, r.indexed_s, speedup,
                r.reference_s < 0 ? "-"
                : r.same          ? "yes"
                                  : "NO");
    std::fflush(stdout);
    all_same = all_same && r.same;
  }
  // Status 1: the two programs disagree, a result that failed.
  return all_same ? markloop::cli::kExitOk : markloop::cli::kExitOutputFailed;
}
