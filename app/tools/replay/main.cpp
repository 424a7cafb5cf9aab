// markloop-replay: runs the sequence engine (or the authors' batch program,
// --compat) on detections recorded in the paper's dataset format.
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <new>
#include <numbers>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "app/common/cli.hpp"
#include "app/common/memory_check.hpp"
#include "app/common/units.hpp"
#include "app/ecu/config.hpp"
#include "app/tools/common/tool_files.hpp"
#include "app/tools/replay/compat.hpp"
#include "app/tools/replay/ecu_detections.hpp"
#include "app/tools/replay/paper_format.hpp"
#include "app/tools/replay/replay.hpp"
#include "app/tools/replay/revisit_events.hpp"
#include "app/tools/replay/revisit_report.hpp"

namespace {

using namespace markloop;
using namespace markloop::replay;
using namespace markloop::cli;

constexpr const char* kUsage = R"(usage: markloop-replay --markings FILE [options]
       markloop-replay --ecu-detections FILE --poses FILE [options]

Runs the online road-marking sequence engine on recorded detections and
prints the loops / places it found.

input:
  --markings FILE        detections, road_marking_centroids_3Dposition.txt
                         format: the record count, then "frame x y z label"
                         per record (y points down; the ground is x-z)
  --ecu-detections FILE  or the ECU's detections (markloop --detections-out),
                         placed on the ground with --poses and gated as the
                         ECU gates them (observation.* defaults). With the
                         ECU's own odometry as --poses (markloop-posegraph's
                         before.kitti) the engine is fed what the car's was
  --poses FILE           one camera pose per frame (KITTI 3x4 [R|t]); the
                         source of travelled distance. Without it, distance
                         is measured along the markings themselves
  --fps HZ               frame rate, for time, 0.001 to 1000000; default 10

engine (each value must lie in the range given):
  --k N                  sequence length, 2 to 10; default 4
  --abs-tol M            distance tolerance, absolute part, 0.001 to 100 m;
                         default 0.5
  --rel-tol R            distance tolerance, relative part, 0 to 0.1;
                         default 0.02
  --min-separation M     a match lies at least this far back, 0 to 10000 m;
                         default 100
  --min-separation-s S   ... and at least this long ago, 0 to 86400 s;
                         default 10
  --max-residual M       largest RMS residual of the rigid fit, 0.001 to
                         100 m; default 0.5
  --association-radius M observations of one marking lie this close, 0.01 to
                         100 m; default 1.5
  --commit-after S       a marking unseen this long has left view, 0.01 to
                         100 s; default 0.5
  --min-observations N   detections needed to make a landmark, 1 to 1000;
                         default 2
  --skip-rows N          rows a sequence may step over, 0 or 1; default 1
  --release-lag M        landmarks enter the chains once the car is this far
                         past them, 0 to 1000 m; default 15
  --settled-lag M        ... or sooner, this far past them once no marking
                         still tracked lies behind them, -1000 to 1000 m
                         (negative: before the car draws level with them);
                         default 15
  --place N              place matching beside the sequences: N recent
                         landmarks agreeing in any order with those stored
                         where the odometry puts the car, 2 to 10; default 0
                         (off: the paper's sequences alone)
  --place-search M       largest drift a place match allows, 1 to 1000 m;
                         default 40
  --place-distinct M     no other place within this distance may fit as
                         well, 1 to 10000 m; default 150
  --place-within M       places are matched only between visits at most this
                         far apart along the drive, 0 to 1000000 m; default
                         2500
  --place-opposite-within M
                         ... and a place of two or of common labels met from
                         the other direction, 0 to 1000000 m; default 2500
  --place-window M       the landmarks released within this much driving
                         make a place, 1 to 1000 m; default 60
  --place-bits B         a place's labels must be rare enough: the sum of
                         -log2 of each label's share of the landmarks seen,
                         0 to 1000; default 0 (any labels)
  --place-pair-bits B    a place of two markings counts when their labels
                         give at least B bits (0 to 1000; default 0: a
                         place needs --place markings)
  --place-pair-unseen N  ... and when at most N stored markings lay, aligned,
                         where the car surely looked and saw none of their
                         label, 0 to 100; default 0
  --place-residual M     a place's rigid fit must be at most this far off
                         (RMS, and within --max-residual), 0.001 to 100 m;
                         default 0.5
  --far-after M          visits further apart along the drive than this, 0
                         to 1000000 m, need a longer run (--far-run); default
                         2500
  --far-run M            ... the run of matches continuing such a match must
                         span this much of the drive, 0 to 100000 m; default 0
  --max-drift-rel R      odometry prior: two visits of a place lie at most
                         5 m + R * distance driven between them apart, 0 to
                         1; default 0 (off)
  --max-frame-distance M a loop's two frames lie at most this far apart by
                         its relative pose, 0 to 10000 m; default 0 (no limit)
  --sequence-capacity N  database size in sequences, 16 to 1073741824 (2^30);
                         default 1048576
  --landmark-capacity N  database size in landmarks, 16 to 1073741824 (2^30);
                         default 262144

  --ecu                  start from the engine settings the ECU ships with
                         (app/ecu/config.hpp: place matching, the odometry
                         prior, ...); the options above change them

  --compat               run the authors' batch program instead: frame gap
                         T = 30, match gap 100 T, distance tolerance 2 m, same
                         matches in the same order (only --k applies); a long
                         run reports its progress on stderr unless --quiet

output:
  --out FILE             matches in the authors' image_matches.txt format
  --jsonl FILE           one JSON record per match, with poses and residuals
  --truth FILE           ground truth (simulator frames.csv or KITTI poses):
                         report correct and wrong matches, revisit recall,
                         relative pose error and the revisit events (6 m,
                         30 s, gaps under 3 s: docs/evaluation.md), each
                         closed at the frame the engine emitted its first
                         correct match (times: frames.csv's, else --fps)
  --truth-radius M       a match is correct when the two frames' true
                         positions are this close, 0.01 to 10000 m; default 10
  --sweep A..B           run k = A..B (2 <= A <= B <= 10) and print a table
                         of matches (and, with --truth, the share of correct
                         ones)
  --quiet                print only the summary
  --help                 this text

Input files are read whole: --markings, --poses and --truth may hold up to
256 MiB each. --poses and --truth must hold a pose for every frame the
markings use. An output may not be one of the input files.

A numeric option that is no number or lies outside its range is refused
(exit status 2) naming the option and its range; the engine checks the
settings as a whole last.

Exit status: 0 on success; 1 when an output cannot be written; 2 on bad
options or input, or a database larger than the memory available.
)";

struct Options {
  std::string markings, ecu_detections, poses, out, jsonl, truth;
  double fps = 10.0;
  double truth_radius = 10.0;
  bool compat = false;
  bool quiet = false;
  unsigned sweep_first = 0, sweep_last = 0;
  EngineConfig engine;
};

// The option table; kUsage above is the help text a user reads.
constexpr OptionSpec kOptions[] = {
    {"--markings", "FILE", "detections, road_marking_centroids_3Dposition.txt format"},
    {"--ecu-detections", "FILE", "the ECU's detections CSV, placed with --poses"},
    {"--poses", "FILE", "one camera pose per frame (KITTI 3x4 [R|t])"},
    {"--fps", "HZ", "frame rate, for time"},
    {"--k", "N", "sequence length"},
    {"--abs-tol", "M", "distance tolerance, absolute part"},
    {"--rel-tol", "R", "distance tolerance, relative part"},
    {"--min-separation", "M", "a match lies at least this far back"},
    {"--min-separation-s", "S", "... and at least this long ago"},
    {"--max-residual", "M", "largest RMS residual of the rigid fit"},
    {"--association-radius", "M", "observations of one marking lie this close"},
    {"--commit-after", "S", "a marking unseen this long has left view"},
    {"--min-observations", "N", "detections needed to make a landmark"},
    {"--skip-rows", "N", "rows a sequence may step over"},
    {"--release-lag", "M", "landmarks enter the chains this far behind the car"},
    {"--settled-lag", "M", "... or this far once no tracked marking lies behind"},
    {"--place", "N", "place matching: N landmarks agreeing in any order"},
    {"--place-search", "M", "largest drift a place match allows"},
    {"--place-distinct", "M", "no other place within this distance may fit as well"},
    {"--place-within", "M", "places only between visits this close along the drive"},
    {"--place-opposite-within", "M", "... and places met from the other direction"},
    {"--place-window", "M", "the landmarks released within this much driving make a place"},
    {"--place-bits", "B", "least evidence of a place's labels, in bits"},
    {"--place-pair-bits", "B", "least evidence of a two-marking place, in bits"},
    {"--place-pair-unseen", "N", "stored markings a two-marking place may leave unseen"},
    {"--place-residual", "M", "largest RMS residual of a place's fit"},
    {"--far-after", "M", "visits this far apart need a longer run"},
    {"--far-run", "M", "the run such a match needs"},
    {"--max-drift-rel", "R", "odometry prior, share of the distance driven"},
    {"--max-frame-distance", "M", "largest distance between a loop's two frames"},
    {"--sequence-capacity", "N", "database size in sequences"},
    {"--landmark-capacity", "N", "database size in landmarks"},
    {"--ecu", "", "start from the engine settings of the ECU"},
    {"--compat", "", "run the authors' batch program instead"},
    {"--out", "FILE", "matches in the authors' image_matches.txt format"},
    {"--jsonl", "FILE", "one JSON record per match"},
    {"--truth", "FILE", "ground truth: report correct and wrong matches"},
    {"--truth-radius", "M", "a match is correct when its frames are this close"},
    {"--sweep", "A..B", "run k = A..B and print a table of matches"},
    {"--quiet", "", "print only the summary"},
};

// The documented range of a numeric option (see kUsage), checked where the
// option is parsed so that the message names it: the engine's validate()
// stays the last check, of the whole configuration.
struct Range {
  double min, max;
  const char* unit;  // "" for a count or a ratio
  bool whole;        // a count: no fractions
};

// A numeric option: its range, and where its value goes.
struct NumericOption {
  std::string_view name;
  Range range;
  void (*set)(Options&, double);
};

constexpr double kCapacityMax = double(std::size_t{1} << 30);

constexpr NumericOption kNumericOptions[] = {
    {"--fps", {0.001, 1e6, "Hz", false}, [](Options& o, double v) { o.fps = v; }},
    {"--truth-radius", {0.01, 10000.0, "metres", false}, [](Options& o, double v) { o.truth_radius = v; }},
    {"--k",
     {2, kMaxSequenceLength, "", true},
     [](Options& o, double v) { o.engine.chain.k = static_cast<unsigned>(v); }},
    {"--abs-tol",
     {0.001, 100.0, "metres", false},
     [](Options& o, double v) { o.engine.match.distance_tolerance_abs_m = v; }},
    {"--rel-tol",
     {0.0, 0.1, "", false},
     [](Options& o, double v) { o.engine.match.distance_tolerance_rel = v; }},
    {"--min-separation",
     {0.0, 10000.0, "metres", false},
     [](Options& o, double v) { o.engine.match.min_separation_m = v; }},
    {"--min-separation-s",
     {0.0, 86400.0, "seconds", false},
     [](Options& o, double v) { o.engine.match.min_separation_s = v; }},
    {"--max-residual",
     {0.001, 100.0, "metres", false},
     [](Options& o, double v) { o.engine.match.max_residual_m = v; }},
    {"--association-radius",
     {0.01, 100.0, "metres", false},
     [](Options& o, double v) { o.engine.tracker.association_radius_m = v; }},
    {"--commit-after",
     {0.01, 100.0, "seconds", false},
     [](Options& o, double v) { o.engine.tracker.commit_after_s = v; }},
    {"--min-observations",
     {1, 1000, "", true},
     [](Options& o, double v) { o.engine.tracker.min_observations = static_cast<unsigned>(v); }},
    {"--skip-rows",
     {0, 1, "", true},
     [](Options& o, double v) { o.engine.chain.max_skipped_rows = static_cast<unsigned>(v); }},
    {"--release-lag",
     {0.0, 1000.0, "metres", false},
     [](Options& o, double v) { o.engine.tracker.release_lag_m = v; }},
    {"--settled-lag",
     {-kMaxSettledLag_m, kMaxSettledLag_m, "metres", false},
     [](Options& o, double v) { o.engine.tracker.settled_lag_m = v; }},
    {"--place",
     {0, kMaxSequenceLength, "", true},
     [](Options& o, double v) { o.engine.match.place_landmarks = static_cast<unsigned>(v); }},
    {"--place-search",
     {1.0, 1000.0, "metres", false},
     [](Options& o, double v) { o.engine.match.place_search_m = v; }},
    {"--place-distinct",
     {1.0, 10000.0, "metres", false},
     [](Options& o, double v) { o.engine.match.place_distinct_m = v; }},
    {"--place-within",
     {0.0, 1e6, "metres", false},
     [](Options& o, double v) { o.engine.match.place_within_m = v; }},
    {"--place-opposite-within",
     {0.0, 1e6, "metres", false},
     [](Options& o, double v) { o.engine.match.place_opposite_within_m = v; }},
    {"--place-window",
     {1.0, 1000.0, "metres", false},
     [](Options& o, double v) { o.engine.match.place_window_m = v; }},
    {"--place-bits",
     {0.0, 1000.0, "", false},
     [](Options& o, double v) { o.engine.match.place_min_bits = v; }},
    {"--place-pair-bits",
     {0.0, 1000.0, "", false},
     [](Options& o, double v) { o.engine.match.place_pair_min_bits = v; }},
    {"--place-pair-unseen",
     {0.0, 100.0, "", true},
     [](Options& o, double v) { o.engine.match.place_pair_max_unseen = static_cast<unsigned>(v); }},
    {"--place-residual",
     {0.001, 100.0, "metres", false},
     [](Options& o, double v) { o.engine.match.place_max_residual_m = v; }},
    {"--far-after",
     {0.0, 1e6, "metres", false},
     [](Options& o, double v) { o.engine.match.far_after_m = v; }},
    {"--far-run", {0.0, 1e5, "metres", false}, [](Options& o, double v) { o.engine.match.far_run_m = v; }},
    {"--max-drift-rel",
     {0.0, 1.0, "", false},
     [](Options& o, double v) { o.engine.match.max_drift_rel = v; }},
    {"--max-frame-distance",
     {0.0, 10000.0, "metres", false},
     [](Options& o, double v) { o.engine.match.max_frame_distance_m = v; }},
    {"--sequence-capacity",
     {16, kCapacityMax, "", true},
     [](Options& o, double v) { o.engine.database.sequence_capacity = static_cast<std::size_t>(v); }},
    {"--landmark-capacity",
     {16, kCapacityMax, "", true},
     [](Options& o, double v) { o.engine.database.landmark_capacity = static_cast<std::size_t>(v); }},
};

// The options that name a file, and where the name goes.
constexpr std::pair<std::string_view, std::string Options::*> kFileOptions[] = {
    {"--markings", &Options::markings}, {"--ecu-detections", &Options::ecu_detections},
    {"--poses", &Options::poses},       {"--out", &Options::out},
    {"--jsonl", &Options::jsonl},       {"--truth", &Options::truth},
};

std::string number_text(double v) {
  char buf[64];
  if (v == std::floor(v) && std::fabs(v) < 1e15)
    std::snprintf(buf, sizeof buf, "%.0f", v);
  else
    std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

// "0.001 to 100 (metres)", "0 to 1".
std::string range_text(const Range& r) {
  std::string text = number_text(r.min) + " to " + number_text(r.max);
  if (*r.unit != '\0') text += std::string(" (") + r.unit + ")";
  return text;
}

// The value of `option` as a number within `r`; fails naming the option and
// the range: "--abs-tol: 2147483648 is outside 0.001 to 100 (metres)".
double parse_in_range(std::string_view option, const char* text, const Range& r) {
  const std::string name(option);
  char* end = nullptr;
  const double value = std::strtod(text, &end);
  const bool parsed = end != text && *end == '\0';
  // Infinity, and what overflows a double (1e999), is a number out of range.
  if (!parsed || std::isnan(value)) fail(name + ": not a number: '" + text + "'; expected " + range_text(r));
  if (!(value >= r.min && value <= r.max)) fail(name + ": " + text + " is outside " + range_text(r));
  if (r.whole && value != std::floor(value))
    fail(name + ": not a whole number: '" + text + "'; expected " + range_text(r));
  return value;
}

// "--sweep A..B": fails unless 2 <= A <= B <= kMaxSequenceLength.
void parse_sweep(const std::string& text, Options& o) {
  const auto dots = text.find("..");
  const std::string expected =
      "--sweep: expected A..B with 2 <= A <= B <= " + std::to_string(kMaxSequenceLength) + ", found '" +
      text + "'";
  if (dots == std::string::npos) fail(expected);
  const auto whole = [&](const std::string& part) {
    char* end = nullptr;
    const double value = std::strtod(part.c_str(), &end);
    if (part.empty() || *end != '\0' || !(value >= 2 && value <= kMaxSequenceLength) ||
        value != std::floor(value))
      fail(expected);
    return static_cast<unsigned>(value);
  };
  o.sweep_first = whole(text.substr(0, dots));
  o.sweep_last = whole(text.substr(dots + 2));
  if (o.sweep_first > o.sweep_last) fail(expected);
}

// One option as given, checked where it stands on the command line.
void apply_option(std::string_view name, const std::string& value, Options& o) {
  if (name == "--compat") o.compat = true;
  if (name == "--quiet") o.quiet = true;
  if (name == "--sweep") parse_sweep(value, o);
  for (const auto& [option, member] : kFileOptions)
    if (name == option) o.*member = value;
  for (const NumericOption& n : kNumericOptions)
    if (name == n.name) n.set(o, parse_in_range(name, value.c_str(), n.range));
}

Options parse(int argc, char** argv) {
  const ParsedArgs args = parse_args_or_fail(argc, argv, kOptions);
  Options o;
  // The ECU's engine settings are the base the other options change, wherever --ecu stands.
  for (const ParsedArgs::Given& given : args.given())
    if (given.name == "--ecu") o.engine = ecu::ecu_engine_defaults();
  // The options before --help are checked as given, as without it.
  for (const ParsedArgs::Given& given : args.given()) apply_option(given.name, std::string(given.value), o);
  if (args.help()) {
    std::fputs(kUsage, stdout);
    std::exit(kExitOk);
  }
  if (o.markings.empty() == o.ecu_detections.empty())
    fail("one of --markings FILE and --ecu-detections FILE is required (see --help)");
  if (!o.ecu_detections.empty() && o.poses.empty())
    fail("--ecu-detections needs --poses: the detections lie in the car's frame");
  // The last check, of the whole configuration (each option was checked above).
  if (const char* problem = validate(o.engine)) fail(std::string("engine settings: ") + problem);
  return o;
}

void write_frames(FILE* f, std::span<const int> frames) {
  for (const int frame : frames) std::fprintf(f, "%d ", frame);
  std::fputc('\n', f);
}

std::vector<int> frames_of(const MatchEvent& e, bool query) {
  std::vector<int> frames;
  for (unsigned i = 0; i < e.k; ++i)
    frames.push_back(static_cast<int>(query ? e.query[i].last_frame : e.match[i].last_frame));
  return frames;
}

void write_jsonl(FILE* f, const MatchEvent& e, const LabelTable& labels, const TruthJudge* judge) {
  const auto positions = [&](const auto& landmarks) {
    std::string s = "[";
    for (unsigned i = 0; i < e.k; ++i) {
      char buf[64];
      std::snprintf(buf, sizeof buf, "%s[%.3f,%.3f]", i ? "," : "", landmarks[i].x, landmarks[i].y);
      s += buf;
    }
    return s + "]";
  };
  const auto frames = [&](bool query) {
    std::string s = "[";
    for (const int frame : frames_of(e, query)) {
      if (s.size() > 1) s += ',';
      s += std::to_string(frame);
    }
    return s + "]";
  };
  std::string label_list = "[";
  for (unsigned i = 0; i < e.k; ++i) {
    label_list += i ? ",\"" : "\"";
    for (const char c : labels.name(e.query[i].label)) {
      if (c == '"' || c == '\\') label_list += '\\';
      label_list += c;
    }
    label_list += '"';
  }
  label_list += "]";
  std::fprintf(f,
               "{\"query_frame\":%u,\"match_frame\":%u,\"query_frames\":%s,\"match_frames\":%s,"
               "\"labels\":%s,\"query_positions\":%s,\"match_positions\":%s,"
               "\"alignment\":{\"dx\":%.4f,\"dy\":%.4f,\"dyaw_deg\":%.3f},",
               e.query_frame(), e.match_frame(), frames(true).c_str(), frames(false).c_str(),
               label_list.c_str(), positions(e.query).c_str(), positions(e.match).c_str(), e.alignment.x,
               e.alignment.y, e.alignment.yaw * kDegreesPerRadian);
  if (e.has_relative_pose)
    std::fprintf(f, "\"relative_pose\":{\"dx\":%.4f,\"dy\":%.4f,\"dyaw_deg\":%.3f},", e.relative_pose.x,
                 e.relative_pose.y, e.relative_pose.yaw * kDegreesPerRadian);
  std::fprintf(f, "\"residual_m\":%.4f,\"score\":%.4f,\"verified_candidates\":%u", e.residual_m, e.score,
               e.verified_candidates);
  if (judge != nullptr && judge->covers(e.query_frame()) && judge->covers(e.match_frame()))
    std::fprintf(f, ",\"correct\":%s", judge->correct({e.query_frame(), e.match_frame()}) ? "true" : "false");
  std::fputs("}\n", f);
}

void print_evaluation(const Evaluation& e) {
  const std::size_t judged = e.correct + e.wrong;
  std::printf("truth: %zu correct, %zu wrong", e.correct, e.wrong);
  if (judged > 0) std::printf(" (precision %.1f%%)", 100.0 * double(e.correct) / double(judged));
  if (e.unjudged > 0) std::printf(", %zu beyond the truth file", e.unjudged);
  std::printf("\n");
  if (e.revisit_segments > 0)
    std::printf("revisits: %zu of %zu revisited 100 m stretches detected (recall %.1f%%)\n",
                e.revisit_segments_detected, e.revisit_segments,
                100.0 * double(e.revisit_segments_detected) / double(e.revisit_segments));
  if (e.pose_errors > 0)
    std::printf("relative pose error: mean %.3f m / %.2f deg, max %.3f m / %.2f deg (%zu matches)\n",
                e.translation_error_mean_m, e.rotation_error_mean_deg, e.translation_error_max_m,
                e.rotation_error_max_deg, e.pose_errors);
}

// A long --compat run says how far it is on stderr, every few seconds.
CompatProgressReport compat_progress(bool quiet) {
  if (quiet) return {};
  using Clock = std::chrono::steady_clock;
  return [next = Clock::now() + std::chrono::seconds(3)](const CompatProgress& p) mutable {
    if (Clock::now() < next) return;
    next = Clock::now() + std::chrono::seconds(3);
    std::fprintf(stderr, "%s: --compat: %zu / %zu records read, %zu sequences made", program_name(),
                 p.records_read, p.records, p.sequences);
    if (p.searched > 0) std::fprintf(stderr, ", %zu / %zu complete ones searched", p.searched, p.complete);
    std::fprintf(stderr, ", %zu matches found\n", p.matches);
  };
}

std::vector<FramePair> compat_pairs(const CompatMatches& matches) {
  std::vector<FramePair> pairs;
  for (std::size_t i = 0; i < matches.size(); ++i)
    pairs.push_back({static_cast<FrameIndex>(matches.later(i).back()),
                     static_cast<FrameIndex>(matches.earlier(i).back())});
  return pairs;
}

// The record that uses the last frame (the first such).
const MarkingRecord* last_frame_record(const std::vector<MarkingRecord>& records) {
  const MarkingRecord* last = nullptr;
  for (const MarkingRecord& r : records)
    if (last == nullptr || r.frame > last->frame) last = &r;
  return last;
}

// The detections' file, whichever option named it.
const std::string& input_path(const Options& o) {
  return o.markings.empty() ? o.ecu_detections : o.markings;
}

// Poses (the odometry) and truth (the judge) are per frame: a file that
// stops short of the markings' frames would leave frames unseen unnoticed.
void check_covers(const std::string& path, std::size_t count, const char* what, const Options& o,
                  const std::vector<MarkingRecord>& records) {
  const MarkingRecord* last = last_frame_record(records);
  if (count == 0 && last == nullptr) fail(path + ": has no " + what + "s");
  if (last == nullptr || count > static_cast<std::size_t>(last->frame)) return;
  fail(path + ": has " + std::to_string(count) + " " + what + (count == 1 ? "" : "s") +
       ", the markings reach frame " + std::to_string(last->frame) + " (" + input_path(o) +
       (last->line > 0 ? ":" + std::to_string(last->line) : std::string()) + "; one " + what +
       " per frame, line i for frame i)");
}

// The engine takes the records in frame order: say so when the file's order
// is another (the paper's files are in frame order).
void warn_unordered(const std::string& path, const std::vector<MarkingRecord>& records) {
  for (std::size_t i = 1; i < records.size(); ++i) {
    if (records[i].frame >= records[i - 1].frame) continue;
    std::fprintf(stderr, "%s: %s:%d: frame %d after frame %d: the records are taken in frame order\n",
                 program_name(), path.c_str(), records[i].line, records[i].frame, records[i - 1].frame);
    return;
  }
}

// An output that is one of the inputs would destroy it: refused before the run.
void check_outputs(const Options& o) {
  const std::pair<const char*, const std::string*> inputs[] = {{"--markings", &o.markings},
                                                               {"--ecu-detections", &o.ecu_detections},
                                                               {"--poses", &o.poses},
                                                               {"--truth", &o.truth}};
  for (const std::string* output : {&o.out, &o.jsonl})
    for (const auto& [option, input] : inputs)
      if (!output->empty() && !input->empty() && platform::overwrites(*output, *input))
        fail(*output + ": is the " + option + " input: an output may not overwrite it");
}

// The database is allocated whole when the engine is built: a size this
// machine cannot hold is refused here, naming the options.
void check_database_fits(const Options& o) {
  const unsigned k = o.sweep_first == 0 ? o.engine.chain.k : o.sweep_last;
  const std::string problem =
      database_memory_error(o.engine.database, k, "--landmark-capacity", "--sequence-capacity");
  if (!problem.empty()) fail(problem);
}

// What every run of the replay works on: the inputs, checked and loaded.
struct Replay {
  Options o;
  std::vector<MarkingRecord> records;
  std::vector<Pose2> poses;
  std::unique_ptr<TruthJudge> judge;
  std::vector<double> truth_times;  // frames.csv's, or frame / fps for KITTI poses
  LabelTable labels;
};

// The value of `loaded`, or fail with its error.
template <class T>
T or_fail(Result<T> loaded) {
  if (!loaded) fail(loaded.message());
  return std::move(loaded).value();
}

void load_inputs(Replay& r) {
  const Options& o = r.o;
  if (!o.poses.empty()) r.poses = or_fail(load_kitti_poses(o.poses));
  if (o.ecu_detections.empty()) {
    r.records = or_fail(load_markings(o.markings));
    warn_unordered(o.markings, r.records);
  } else {
    EcuDetections ecu = or_fail(load_ecu_detections(o.ecu_detections, r.poses, ecu::ObservationGate{}));
    std::fprintf(stderr, "%s: %s: %zu detections, %zu of them refused by the ECU's observation gate\n",
                 program_name(), o.ecu_detections.c_str(), ecu.detections, ecu.gated);
    r.records = std::move(ecu.records);
  }
  if (!o.poses.empty()) check_covers(o.poses, r.poses.size(), "pose", o, r.records);
  if (!o.compat) check_database_fits(o);
  if (o.truth.empty()) return;
  TruePoses truth = or_fail(load_truth(o.truth));
  check_covers(o.truth, truth.poses.size(), "true pose", o, r.records);
  r.truth_times = std::move(truth.times);
  for (std::size_t f = r.truth_times.size(); f < truth.poses.size(); ++f)
    r.truth_times.push_back(static_cast<double>(f) / o.fps);
  r.judge =
      std::make_unique<TruthJudge>(std::move(truth.poses), o.truth_radius, o.engine.match.min_separation_m);
}

// Opens `path`, lets `write` fill it, and closes it; a failed write fails the run.
template <class Write>
void write_output(const std::string& path, Write write) {
  tools::OutputFile f;
  if (const Status opened = f.open(path); !opened) tools::fail_run(opened.message());
  write(f.get());
  if (const Status closed = f.close(); !closed) tools::fail_run(closed.message());
}

std::vector<FramePair> run_compat_once(const Replay& r, unsigned k, bool write) {
  CompatParameters parameters;
  parameters.k = k;
  const auto matches = run_compat(r.records, parameters, compat_progress(r.o.quiet));
  if (write && !r.o.out.empty())
    write_output(r.o.out, [&](FILE* f) {
      for (std::size_t i = 0; i < matches.size(); ++i) {
        write_frames(f, matches.earlier(i));
        write_frames(f, matches.later(i));
      }
    });
  return compat_pairs(matches);
}

void write_engine_outputs(const Replay& r, const ReplayResult& result) {
  if (!r.o.out.empty())
    write_output(r.o.out, [&](FILE* f) {
      for (const MatchEvent& e : result.matches) {
        write_frames(f, frames_of(e, false));
        write_frames(f, frames_of(e, true));
      }
    });
  if (!r.o.jsonl.empty())
    write_output(r.o.jsonl, [&](FILE* f) {
      for (const MatchEvent& e : result.matches) write_jsonl(f, e, r.labels, r.judge.get());
    });
}

void print_counters(const Replay& r, const ReplayResult& result, unsigned k) {
  const auto& c = result.counters;
  std::printf(
      "markloop-replay: %zu detections in %zu frames -> %llu landmarks, %llu sequences "
      "of k=%u, %llu queries, %llu candidates (%llu too recent, %llu failed the rigid "
      "fit)\n",
      r.records.size(), result.frames, (unsigned long long)c.landmarks_released,
      (unsigned long long)c.sequences_created, k, (unsigned long long)c.queries,
      (unsigned long long)c.candidates, (unsigned long long)c.candidates_too_recent,
      (unsigned long long)c.candidates_rejected_residual);
  const PlaceCounters& p = result.places;
  if (p.queries > 0)
    std::printf(
        "markloop-replay: places: %llu queries, %llu hypotheses (%llu with too few pairs, %llu failed the "
        "rigid fit), %llu beyond the drift limits, %llu ambiguous, %llu too common, %llu of two across "
        "roads, "
        "%llu of two with a marking unseen, %llu matches\n",
        (unsigned long long)p.queries, (unsigned long long)p.hypotheses, (unsigned long long)p.too_few_pairs,
        (unsigned long long)p.rejected_residual, (unsigned long long)p.rejected_drift,
        (unsigned long long)p.ambiguous, (unsigned long long)p.too_common, (unsigned long long)p.across,
        (unsigned long long)p.unseen, (unsigned long long)p.matches);
  if (c.matches_held_far > 0)
    std::printf("markloop-replay: %llu sequence matches held back (visits far apart, run too short)\n",
                (unsigned long long)c.matches_held_far);
  if (const std::optional<ScaleEstimate>& scale = result.odometry_scale)
    std::printf(
        "markloop-replay: odometry scale by the markings %.5f +- %.5f (%u markings; "
        "markloop-posegraph --camera-scale)\n",
        scale->scale, scale->standard_error, scale->markings);
}

void print_loop(const Replay& r, const MatchEvent& e) {
  std::printf("  loop: frame %u matches frame %u  [", e.query_frame(), e.match_frame());
  for (unsigned i = 0; i < e.k; ++i)
    std::printf("%s%s", i ? " " : "", r.labels.name(e.query[i].label).c_str());
  std::printf("]  residual %.3f m  score %.2f", e.residual_m, e.score);
  if (e.has_relative_pose)
    std::printf("  relative pose (%.2f m, %.2f m, %.1f deg)", e.relative_pose.x, e.relative_pose.y,
                e.relative_pose.yaw * kDegreesPerRadian);
  const TruthJudge* judge = r.judge.get();
  if (judge && judge->covers(e.query_frame()) && judge->covers(e.match_frame()) &&
      !judge->correct({e.query_frame(), e.match_frame()}))
    std::printf("  WRONG");
  std::printf("\n");
}

// The table lists this many revisit events.
constexpr std::size_t kListedRevisits = 20;

// The revisit events of the truth, each closed by the first correct match
// with its query frame in it, counted at the frame the engine emitted it.
void print_revisits(const Replay& r, const ReplayResult& result) {
  const TruthJudge& judge = *r.judge;
  std::vector<ClosingDetection> closing;
  for (std::size_t i = 0; i < result.matches.size(); ++i) {
    const FramePair pair{result.matches[i].query_frame(), result.matches[i].match_frame()};
    const bool correct = judge.covers(pair.query) && judge.covers(pair.match) && judge.correct(pair);
    closing.push_back({pair.query, result.emitted_at[i], correct});
  }
  std::vector<RevisitEvent> events = find_revisit_events(judge.truth(), r.truth_times);
  close_revisit_events(events, judge.truth(), closing);
  print_revisit_tally(stdout, tally_revisit_events(events));
  print_revisit_events(stdout, events, kListedRevisits);
}

// One engine run with sequences of `k`; with `write`, its outputs and report.
std::vector<FramePair> run_engine_once(Replay& r, unsigned k, bool write) {
  EngineConfig config = r.o.engine;
  config.chain.k = k;
  const ReplayResult result = run_engine(r.records, r.poses, r.labels, config, r.o.fps);
  std::vector<FramePair> pairs = frame_pairs(result.matches);
  if (!write) return pairs;
  write_engine_outputs(r, result);
  print_counters(r, result, k);
  if (!r.o.quiet)
    for (const MatchEvent& e : result.matches) print_loop(r, e);
  std::printf("matches: %zu\n", result.matches.size());
  if (!r.judge) return pairs;
  print_evaluation(r.judge->evaluate(pairs, relative_poses(result.matches)));
  print_revisits(r, result);
  return pairs;
}

// One run: returns the frame pairs found, writing outputs when asked.
std::vector<FramePair> run_once(Replay& r, unsigned k, bool write) {
  return r.o.compat ? run_compat_once(r, k, write) : run_engine_once(r, k, write);
}

void run_single(Replay& r) {
  const unsigned k = r.o.engine.chain.k;
  const auto pairs = run_once(r, k, true);
  if (!r.o.compat) return;
  std::printf("markloop-replay --compat: %zu records -> %zu matches (k=%u)\n", r.records.size(), pairs.size(),
              k);
  if (r.judge) print_evaluation(r.judge->evaluate(pairs));
}

// A sweep table row of percentages: part / judged, or "-" when none was judged.
void print_share_row(const char* name, const std::vector<std::size_t>& part,
                     const std::vector<std::size_t>& judged) {
  std::printf("\n%-22s", name);
  for (std::size_t i = 0; i < judged.size(); ++i)
    judged[i] ? std::printf(" %6.1f", 100.0 * double(part[i]) / double(judged[i])) : std::printf(" %6s", "-");
}

void run_sweep(Replay& r) {
  std::printf("%-22s", "Search window size");
  for (unsigned k = r.o.sweep_first; k <= r.o.sweep_last; ++k) std::printf(" %6u", k);
  std::vector<std::size_t> counts, correct, wrong, judged;
  for (unsigned k = r.o.sweep_first; k <= r.o.sweep_last; ++k) {
    const auto pairs = run_once(r, k, false);
    counts.push_back(pairs.size());
    if (!r.judge) continue;
    const Evaluation e = r.judge->evaluate(pairs);
    correct.push_back(e.correct);
    wrong.push_back(e.wrong);
    judged.push_back(e.correct + e.wrong);
  }
  std::printf("\n%-22s", "Number of matches");
  for (const std::size_t c : counts) std::printf(" %6zu", c);
  if (r.judge) {
    print_share_row("Correct matches (%)", correct, judged);
    print_share_row("Incorrect matches (%)", wrong, judged);
  }
  std::printf("\n");
}

int replay_main(int argc, char** argv) {
  Replay r{parse(argc, argv), {}, {}, {}, {}, {}};
  check_outputs(r.o);
  load_inputs(r);
  if (r.o.sweep_first == 0)
    run_single(r);
  else
    run_sweep(r);
  if (const Status flushed = tools::flush_stdout(); !flushed) tools::fail_run(flushed.message());
  return kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  program_name() = "markloop-replay";
  try {
    return replay_main(argc, argv);
  } catch (const std::bad_alloc&) {
    // Inputs and the database are checked against their limits first: this
    // is what no check foresaw (another program took the memory meanwhile).
    fail(
        "out of memory: the input or the database (--landmark-capacity, --sequence-capacity) is "
        "too large for the memory available");
  }
}
