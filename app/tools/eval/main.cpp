// markloop-eval: judges a run of the ECU against the simulator's truth: loop
// precision and revisit recall, relative pose error, latency on the bus, and
// marking detection/classification; draws the run as SVG and PNG.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "app/common/cli.hpp"
#include "app/tools/common/tool_files.hpp"
#include "app/tools/eval/can_log.hpp"
#include "app/tools/eval/drive_summary.hpp"
#include "app/tools/eval/figure.hpp"
#include "app/tools/eval/inputs.hpp"
#include "app/tools/eval/scoring.hpp"
#include "app/tools/replay/paper_format.hpp"
#include "app/tools/replay/revisit_events.hpp"
#include "app/tools/replay/revisit_report.hpp"
#include "app/tools/replay/truth_judge.hpp"

namespace {

using namespace markloop;
using namespace markloop::eval;
using namespace markloop::cli;

// Same as the engine's default minimum separation: a revisit is a return to
// a place driven at least this far before (see TruthJudge).
constexpr double kRevisitSeparation_m = 100.0;

constexpr const char* kUsage = R"(usage: markloop-eval DIR [options]
       markloop-eval --summary EVAL_JSON... [--json FILE]

Judges what the markloop ECU sent on CAN for a simulated drive against the
simulator's ground truth, prints a table of figures and draws the run.

DIR holds the simulator's frames.csv (frame,t,x,y,yaw), markings.csv
(id,class,x,y,heading) and visible.csv (frame,id,class,x1,y1,...,x4,y4), and
by default the ECU's outputs.

options:
  --can FILE         the ECU's CAN output, candump -l log; default DIR/ecu-can.log
  --detections FILE  the ECU's --detections-out CSV; default DIR/ecu-detections.csv
                     (when the default file is absent the marking section is
                     skipped with a note)
  --landmarks FILE   the ECU's --landmarks-out CSV; default DIR/ecu-landmarks.csv
                     (when the default file is absent the landmark sections
                     are skipped with a note; markings driven past also need
                     the detections)
  --tolerance M      a loop detection is correct when the true positions of its
                     two frames are within M metres (up to 10000); also the
                     radius of a revisit; default 5
  --svg FILE         picture of the run; default DIR/loops.svg
  --png FILE         the same picture as PNG; default DIR/loops.png
  --json FILE        every figure as JSON, for scripts
  --corrected FILE   a corrected trajectory (TUM, markloop-posegraph's
                     after.tum), drawn in the picture aligned to the truth
  --summary          read the eval.json files given (of this markloop-eval,
                     one per drive) instead of a run and print their sum:
                     drives, km, revisit events closed / total by kind and
                     length, median and p90 closure distance, wrong loop
                     detections (and the drives that had them), relative
                     pose error mean over all detections; --json FILE writes
                     it as JSON (tests/loops/revisit-table.sh runs the drives)
  --help             this text

figures:
  loop precision     correct / judged LoopDetection messages
  revisit recall     revisited 100 m stretches of the route (places driven
                     again at least 100 m later) with a correct detection
  revisit events     frames within 6 m of a frame at least 30 s older, joined
                     while the gaps are under 3 s: per event its length, kind
                     (same direction, opposite direction, crossing/turn-in)
                     and how far into it the car had driven when the first
                     correct detection with its query frame in it reached
                     the bus, or never; closed / events by kind and length
                     (under 50 m, 50 m or more), median and p90 of that
                     distance
  pose error         PoseDx/PoseDy/PoseDyaw of correct detections against the
                     true pose of the car at the query in the car's frame at
                     the match
  latency            CAN frame timestamp of a detection's last page minus its
                     QueryTime (the capture time of the frame that completed
                     it: the end-to-end latency), minus the time of its
                     QueryFrame (frames.csv), and minus the latest frame at or
                     before it: median, p99, max
  markings           a detection matches a visible marking of its frame when
                     its quad's centre lies inside the marking's quad or their
                     IoU is at least 0.3 (one to one); detection recall and
                     precision (any label), classification accuracy (right
                     label among matched), per class
  landmarks          each of the ECU's landmarks placed in the truth's world
                     by its offset from the car at its last frame (the
                     odometry's drift cancels): on a marking of its label, on
                     one of another class, or on none (the nearest within
                     2 m; of a crosswalk, anywhere across the road)
  markings driven    each pass of the car by a marking (the frames showing
  past               it, gaps under 5 s) whose centre came 3..20 m ahead and
                     within 6 m to a side: named right or wrong by the
                     landmark the ECU made of it (on it, seen during the pass
                     or up to 1 s around it), or no landmark; with its
                     detections (matched to it, or within 1.5 m of it on the
                     ground where visible.csv does not show it). A marking in
                     view at the drive's first frame, or passed less than
                     40 m before its end, is not judged

Each input file is read whole and may hold up to 256 MiB; no output may be
one of them. The CAN log's stamps must be the drive's clock (as the ECU
stamps it in file mode): in send order, from 10 s before frames.csv's first
frame to 60 s after its last; a last line cut short is an error. Frames of
the wrong length on the ECU's ids, and a log without any frame of the ECU,
are warned about on stderr.

Exit status: 0 on success; 1 when an output cannot be written (PATH: why);
2 on bad input or options (FILE:LINE: what).
)";

struct Options {
  std::string dir, can, detections, svg, png, json, corrected;
  bool summary = false;
  std::vector<std::string> summary_files;
  bool detections_given = false;
  std::string landmarks;
  bool landmarks_given = false;
  double tolerance = 5.0;
};

// The option table; kUsage above is the help text a user reads.
constexpr OptionSpec kOptions[] = {
    {"--can", "FILE", "the ECU's CAN output, candump -l log"},
    {"--detections", "FILE", "the ECU's --detections-out CSV"},
    {"--landmarks", "FILE", "the ECU's --landmarks-out CSV"},
    {"--tolerance", "M", "a loop detection is correct within M metres"},
    {"--svg", "FILE", "picture of the run"},
    {"--png", "FILE", "the same picture as PNG"},
    {"--json", "FILE", "every figure as JSON, for scripts"},
    {"--corrected", "FILE", "a corrected trajectory (TUM) to draw"},
    {"--summary", "", "sum the eval.json files given"},
};

// One option as given, checked where it stands on the command line.
void apply_option(std::string_view name, std::string_view value, Options& o) {
  if (name == "--can") o.can = value;
  if (name == "--detections") o.detections = value, o.detections_given = true;
  if (name == "--landmarks") o.landmarks = value, o.landmarks_given = true;
  if (name == "--tolerance") o.tolerance = parse_number(name, std::string(value).c_str());
  if (name == "--svg") o.svg = value;
  if (name == "--png") o.png = value;
  if (name == "--json") o.json = value;
  if (name == "--corrected") o.corrected = value;
  if (name == "--summary") o.summary = true;
}

// --summary takes eval.json files, and of the options only --json.
void check_summary(const ParsedArgs& args, Options& o) {
  for (const ParsedArgs::Given& given : args.given())
    if (given.name != "--summary" && given.name != "--json")
      fail(std::string(given.name) + " does not apply with --summary (only --json does)");
  for (const std::string_view file : args.positional()) o.summary_files.emplace_back(file);
  if (o.summary_files.empty()) fail("--summary needs eval.json files (see --help)");
  for (const std::string& file : o.summary_files)
    if (!o.json.empty() && platform::overwrites(o.json, file))
      fail(o.json + ": is the input " + file + ": an output may not overwrite it");
}

// The outputs and inputs not given, in DIR.
void default_paths(Options& o) {
  const std::filesystem::path dir(o.dir);
  if (o.can.empty()) o.can = dir / "ecu-can.log";
  if (o.detections.empty()) o.detections = dir / "ecu-detections.csv";
  if (o.landmarks.empty()) o.landmarks = dir / "ecu-landmarks.csv";
  if (o.svg.empty()) o.svg = dir / "loops.svg";
  if (o.png.empty()) o.png = dir / "loops.png";
}

Options parse(int argc, char** argv) {
  const ParsedArgs args = parse_args_or_fail(argc, argv, kOptions, 0, static_cast<std::size_t>(argc));
  Options o;
  // The options before --help are checked as given, as without it.
  for (const ParsedArgs::Given& given : args.given()) apply_option(given.name, given.value, o);
  const auto& dirs = args.positional();
  // A lone "-" is no directory: standard input is not read.
  if (std::find(dirs.begin(), dirs.end(), "-") != dirs.end()) fail("unknown option - (see --help)");
  if (o.summary && !args.help()) {
    check_summary(args, o);
    return o;
  }
  if (dirs.size() > 1)
    fail("more than one DIR given: '" + std::string(dirs[0]) + "' and '" + std::string(dirs[1]) + "'");
  if (args.help()) {
    std::fputs(kUsage, stdout);
    std::exit(kExitOk);
  }
  if (dirs.empty()) fail("DIR is required (see --help)");
  o.dir = dirs[0];
  if (!(o.tolerance > 0 && o.tolerance <= 10000)) fail("--tolerance must be in (0, 10000] metres");
  default_paths(o);
  return o;
}

// An output that is one of the inputs would destroy it: refused before the run.
void check_outputs(const Options& o) {
  const std::filesystem::path dir(o.dir);
  const std::string inputs[] = {dir / "frames.csv", dir / "markings.csv", dir / "visible.csv", o.can,
                                o.detections,       o.landmarks,          o.corrected};
  for (const std::string* output : {&o.svg, &o.png, &o.json})
    for (const std::string& input : inputs)
      if (!output->empty() && !input.empty() && platform::overwrites(*output, input))
        fail(*output + ": is the input " + input + ": an output may not overwrite it");
}

double percent(std::size_t part, std::size_t whole) {
  return whole == 0 ? 0.0 : 100.0 * static_cast<double>(part) / static_cast<double>(whole);
}

// "12.5 %" or "-" when there is nothing to divide by.
std::string percent_text(std::size_t part, std::size_t whole) {
  if (whole == 0) return "-";
  char text[32];
  std::snprintf(text, sizeof text, "%.1f %%", percent(part, whole));
  return text;
}

double route_length_m(const std::vector<Pose2>& route) {
  double length = 0.0;
  for (std::size_t i = 1; i < route.size(); ++i)
    length += std::hypot(route[i].x - route[i - 1].x, route[i].y - route[i - 1].y);
  return length;
}

void print_rejects(const char* name, const RejectCounts& r) {
  std::printf("  %-14s %8llu accepted, %llu rejected", name, (unsigned long long)r.accepted,
              (unsigned long long)r.rejected());
  if (r.rejected() > 0)
    std::printf(" (CRC %llu, alive counter %llu, length %llu, range %llu, page %llu)",
                (unsigned long long)r.bad_crc, (unsigned long long)r.bad_counter,
                (unsigned long long)r.wrong_length, (unsigned long long)r.out_of_range,
                (unsigned long long)r.unknown_page);
  std::printf("\n");
}

void print_spread(const char* name, const Spread& s, double unit, const char* unit_name) {
  if (s.count == 0) {
    std::printf("  %-34s -\n", name);
    return;
  }
  std::printf("  %-34s %.1f / %.1f / %.1f %s (min %.1f, %zu)\n", name, s.median * unit, s.p99 * unit,
              s.max * unit, unit_name, s.min * unit, s.count);
}

void json_rejects(std::FILE* f, const char* name, const RejectCounts& r) {
  std::fprintf(f,
               "\"%s\":{\"accepted\":%llu,\"bad_crc\":%llu,\"bad_counter\":%llu,\"wrong_length\":%llu,"
               "\"out_of_range\":%llu,\"unknown_page\":%llu}",
               name, (unsigned long long)r.accepted, (unsigned long long)r.bad_crc,
               (unsigned long long)r.bad_counter, (unsigned long long)r.wrong_length,
               (unsigned long long)r.out_of_range, (unsigned long long)r.unknown_page);
}

void json_spread(std::FILE* f, const char* name, const Spread& s) {
  std::fprintf(f, "\"%s\":{\"count\":%zu,\"median\":%.6f,\"p99\":%.6f,\"max\":%.6f,\"min\":%.6f}", name,
               s.count, s.median, s.p99, s.max, s.min);
}

const char* outcome_name(PassOutcome o) {
  switch (o) {
    case PassOutcome::NamedRight:
      return "named_right";
    case PassOutcome::NamedWrong:
      return "named_wrong";
    case PassOutcome::NoLandmark:
      return "no_landmark";
  }
  return "?";
}

std::string class_name(Label label) {
  return label < perception::kMarkingClassCount ? std::string(perception::kMarkingClassNames[label]) : "?";
}

// The table lists this many landmarks or passes of each kind; --json all.
constexpr std::size_t kListed = 20;
// ... and this many revisit events.
constexpr std::size_t kListedRevisits = 40;

// "another class" or "on no marking", for a landmark the score lists.
const char* misplacement(const LandmarkScore& l, const MisplacedLandmark& m) {
  return l.marking_of[m.landmark] ? "another class" : "on no marking";
}

void print_landmarks(const LandmarkScore& l, const std::vector<LandmarkRecord>& landmarks,
                     const std::vector<WorldMarking>& world) {
  const std::size_t placed = l.landmarks - l.without_pose;
  std::printf(
      "\nLandmarks (the ECU's, placed by their offset from the car at their last frame; on a\n"
      "marking: the nearest within %.1f m, of a crosswalk anywhere across the road)\n",
      kLandmarkOnMarking_m);
  std::printf("  %-34s %zu (%zu without the car's pose, not judged)\n", "landmarks", l.landmarks,
              l.without_pose);
  std::printf("  %-34s %s (%zu)\n", "on a marking of their label",
              percent_text(l.right_label, placed).c_str(), l.right_label);
  std::printf("  %-34s %zu\n", "on a marking of another class", l.wrong_label);
  std::printf("  %-34s %zu\n", "on no marking", l.on_nothing);
  if (l.distance_m.count > 0)
    std::printf("  %-34s %.2f / %.2f / %.2f m\n", "distance to it, median / p99 / max", l.distance_m.median,
                l.distance_m.p99, l.distance_m.max);
  for (std::size_t i = 0; i < l.misplaced.size() && i < kListed; ++i) {
    const MisplacedLandmark& m = l.misplaced[i];
    const LandmarkRecord& r = landmarks[m.landmark];
    std::printf("    %s: landmark %zu (%s), frames %u..%u, at (%.1f, %.1f) m", misplacement(l, m),
                m.landmark + 1, class_name(r.label).c_str(), r.first_frame, r.last_frame, m.x, m.y);
    if (m.nearest)
      std::printf("; nearest marking %u (%s), %.2f m", world[*m.nearest].id,
                  class_name(world[*m.nearest].label).c_str(), m.distance_m);
    std::printf("\n");
  }
  if (l.misplaced.size() > kListed)
    std::printf("    ... %zu more (all in --json)\n", l.misplaced.size() - kListed);
}

void print_passes(const PassScore& p) {
  const std::size_t total = p.passes.size();
  const PassRegion region;
  std::printf(
      "\nMarkings driven past (a pass: the frames showing a marking, gaps under %.0f s; counted\n"
      "when its centre came %.0f..%.0f m ahead and within %.0f m to a side; named by the landmark\n"
      "the ECU made of it on that pass)\n",
      kPassGap_s, region.ahead_min_m, region.ahead_max_m, region.side_m);
  std::printf("  %-34s %zu (and %zu at the drive's start or end, not judged)\n", "passes", total,
              p.cut_by_drive_ends);
  std::printf("  %-34s %s (%zu)\n", "named right",
              percent_text(p.count(PassOutcome::NamedRight), total).c_str(),
              p.count(PassOutcome::NamedRight));
  std::printf("  %-34s %zu\n", "named wrong", p.count(PassOutcome::NamedWrong));
  std::printf("  %-34s %zu\n", "no landmark", p.count(PassOutcome::NoLandmark));
  std::printf("  %-14s %8s %8s %8s\n", "class", "passes", "right", "share");
  for (std::size_t c = 0; c < p.passes_of_class.size(); ++c) {
    if (p.passes_of_class[c] == 0) continue;
    std::printf("  %-14s %8zu %8zu %8s\n", class_name(static_cast<Label>(c)).c_str(), p.passes_of_class[c],
                p.named_right_of_class[c],
                percent_text(p.named_right_of_class[c], p.passes_of_class[c]).c_str());
  }
  std::size_t listed = 0, unlisted = 0;
  for (const MarkingPass& pass : p.passes) {
    if (pass.outcome == PassOutcome::NamedRight) continue;
    if (listed == kListed) {
      ++unlisted;
      continue;
    }
    ++listed;
    std::printf("    %s: marking %u (%s), frames %u..%u, %zu detections", outcome_name(pass.outcome), pass.id,
                class_name(pass.label).c_str(), pass.first_frame, pass.last_frame, pass.detections);
    if (pass.outcome == PassOutcome::NamedWrong) std::printf(", named %s", class_name(pass.named).c_str());
    std::printf("\n");
  }
  if (unlisted > 0) std::printf("    ... %zu more (all in --json)\n", unlisted);
}

// Everything judged of one run: the truth, the ECU's outputs and their scores.
struct Run {
  Options o;
  std::vector<Pose2> route;  // true pose per frame
  std::vector<double> times;
  double length_m = 0.0;
  std::vector<WorldMarking> world;
  EcuCanLog log;
  LoopScore loops;
  std::vector<replay::RevisitEvent> revisits;  // in the truth, closed by the ECU's detections
  replay::RevisitTally revisit_tally;
  std::vector<VisibleMarking> visible;
  bool have_visible = false;
  std::vector<DetectionRecord> detections;
  std::string marking_note;  // why the markings were not judged
  bool have_markings = false;
  MarkingScore markings;
  std::vector<LandmarkRecord> landmarks;
  std::string landmark_note;  // why the landmarks were not judged
  bool have_landmarks = false;
  LandmarkScore placed;
  // A pass's detections are told with it: it needs both files.
  bool have_passes = false;
  PassScore passes;
};

// The value of `loaded`, or fail with its error.
template <class T>
T or_fail(Result<T> loaded) {
  if (!loaded) fail(loaded.message());
  return std::move(loaded).value();
}

// Truth: frames.csv must be the simulator's, with its header (KITTI poses
// carry no times).
void load_route(Run& r) {
  const std::string frames_path = std::filesystem::path(r.o.dir) / "frames.csv";
  replay::TruePoses truth = or_fail(replay::load_frames_csv(frames_path));
  r.route = std::move(truth.poses);
  r.times = std::move(truth.times);
  if (r.route.empty()) fail(frames_path + ": no frames");
  for (std::size_t i = 1; i < r.times.size(); ++i)
    if (!(r.times[i] > r.times[i - 1]))
      fail(frames_path + ":" + std::to_string(i + 2) + ": time does not increase");
  r.length_m = route_length_m(r.route);
}

// The log's stamps must be the drive's clock (frames.csv's times).
void load_can_log(Run& r) {
  const DriveTimes drive{r.times.empty() ? 0.0 : r.times.front(), r.times.empty() ? 0.0 : r.times.back()};
  r.log = or_fail(read_ecu_can_log(r.o.can, r.times.empty() ? nullptr : &drive));
  for (const std::string& warning : can_log_warnings(r.o.can, r.log))
    std::fprintf(stderr, "%s: warning: %s\n", program_name(), warning.c_str());
}

// The ECU's detections and landmarks, each skipped with a note when its
// default file is absent.
void load_ecu_outputs(Run& r) {
  const Options& o = r.o;
  // The markings in view judge the detections (then they must be there),
  // and tell what each revisit shares with the older visit.
  const bool judge_detections = o.detections_given || std::filesystem::exists(o.detections);
  const std::string visible = std::filesystem::path(o.dir) / "visible.csv";
  r.have_visible = judge_detections || std::filesystem::exists(visible);
  if (r.have_visible) r.visible = or_fail(load_visible(visible, r.route.size()));
  if (!judge_detections) {
    r.marking_note = o.detections + " not found: marking detection not evaluated";
  } else {
    r.detections = or_fail(load_detections(o.detections, r.route.size()));
    r.have_markings = true;
  }
  if (!o.landmarks_given && !std::filesystem::exists(o.landmarks)) {
    r.landmark_note = o.landmarks + " not found: landmarks not evaluated";
  } else {
    r.landmarks = or_fail(load_landmarks(o.landmarks, r.route.size()));
    r.have_landmarks = true;
  }
  r.have_passes = r.have_landmarks && r.have_markings;
}

// Each marking in view where it lies from the car (one of the world's
// markings: a view of an unknown one is left out).
std::vector<replay::MarkingView> marking_views(const Run& r) {
  std::unordered_map<std::uint32_t, const WorldMarking*> by_id;
  for (const WorldMarking& m : r.world) by_id.emplace(m.id, &m);
  std::vector<replay::MarkingView> views;
  views.reserve(r.visible.size());
  for (const VisibleMarking& v : r.visible) {
    const auto m = by_id.find(v.id);
    if (m == by_id.end() || v.frame >= r.route.size()) continue;
    const Pose2& car = r.route[v.frame];
    const Pose2 at = compose(inverse(car), Pose2{m->second->x, m->second->y, 0.0});
    views.push_back({v.frame, v.id, at.x, at.y});
  }
  return views;
}

// The passes of which the ECU made a landmark, with its label.
std::vector<replay::LandmarkedPass> landmarked_passes(const PassScore& passes) {
  std::vector<replay::LandmarkedPass> landmarked;
  for (const MarkingPass& p : passes.passes)
    if (p.outcome != PassOutcome::NoLandmark) landmarked.push_back({p.last_frame, p.id, p.named});
  return landmarked;
}

void score(Run& r) {
  const replay::TruthJudge judge(r.route, r.o.tolerance, kRevisitSeparation_m);
  r.loops = score_loops(judge, r.times, r.log.loops);
  r.revisits = replay::find_revisit_events(r.route, r.times);
  replay::close_revisit_events(r.revisits, r.route, closing_detections(r.loops, r.log.loops, r.times));
  if (r.have_visible) replay::mark_shared_markings(r.revisits, r.route, r.times, marking_views(r));
  if (r.have_markings) r.markings = score_markings(r.visible, r.detections);
  if (r.have_landmarks) r.placed = score_landmarks(r.world, r.route, r.landmarks);
  if (r.have_passes) {
    r.passes =
        score_passes(r.world, r.route, r.times, r.visible, r.detections, r.markings, r.landmarks, r.placed);
    replay::mark_landmarked_markings(r.revisits, r.route, r.times, landmarked_passes(r.passes));
  }
  r.revisit_tally = replay::tally_revisit_events(r.revisits);
}

void print_can(const Run& r) {
  const EcuCanLog& log = r.log;
  std::printf("markloop-eval: %s: %zu frames (%.1f s), route %.2f km, %zu markings in the world\n",
              r.o.dir.c_str(), r.route.size(), r.times.back() - r.times.front(), r.length_m / 1000.0,
              r.world.size());
  std::printf("\nCAN output %s: %llu frames\n", r.o.can.c_str(), (unsigned long long)log.frames);
  print_rejects("LoopDetection", log.loop_frames);
  print_rejects("Status", log.status_frames);
  if (log.other_frames > 0) std::printf("  %-14s %8llu\n", "other ids", (unsigned long long)log.other_frames);
  std::printf("  %-14s %8zu complete, %llu incomplete (a page missing or rejected)\n", "detections",
              log.loops.size(), (unsigned long long)log.detections_incomplete);
}

void print_status(const EcuCanLog& log) {
  const StatusSummary& s = log.status;
  if (log.status_frames.accepted == 0) return;
  std::printf("\nECU status (last values)\n");
  std::printf("  %-34s %s\n", "state", std::string(dbc::to_string(s.last.system_state)).c_str());
  if (s.page_seen[0])
    std::printf("  %-34s %u (database %.1f %% full)\n", "frames processed", s.last.frames_processed,
                s.last.database_fill_percent);
  if (s.page_seen[1]) {
    std::printf("  %-34s %u\n", "frames dropped", s.last.frames_dropped);
    std::printf("  %-34s %.2f ms\n", "longest loop time (any cycle)", s.loop_time_max_ms);
  }
  if (s.page_seen[2])
    std::printf("  %-34s %u landmarks, %u sequences\n", "database", s.last.landmark_count,
                s.last.sequence_count);
  if (s.page_seen[3]) std::printf("  %-34s %u\n", "frames showing no road", s.last.frames_blind);
  if (s.page_seen[4] && s.last.odometry_scale_valid)
    std::printf("  %-34s %.5f +- %.5f\n", "odometry scale by the camera", s.last.odometry_scale,
                s.last.odometry_scale_error);
  else if (s.page_seen[4])
    std::printf("  %-34s none yet\n", "odometry scale by the camera");
  std::printf(
      "  %-34s camera lost %llu, camera blind %llu, odometry timeout %llu, bus error %llu, "
      "overrun %llu\n",
      "Status frames with a fault", (unsigned long long)s.camera_lost, (unsigned long long)s.camera_blind,
      (unsigned long long)s.odometry_timeout, (unsigned long long)s.bus_error, (unsigned long long)s.overrun);
}

void print_wrong_loops(const LoopScore& loops) {
  for (const LoopOutcome& l : loops.outcomes) {
    if (l.verdict != Verdict::Wrong) continue;
    std::printf("    wrong: frame %u against frame %u, %.1f m apart", l.pair.query, l.pair.match,
                l.true_distance_m);
    if (l.pose_error)
      std::printf(" (relative pose error %.3f m, %.2f deg)", l.pose_error->translation_m,
                  l.pose_error->rotation_deg);
    std::printf("\n");
  }
}

void print_pose_error_and_latency(const LoopScore& loops) {
  const replay::Evaluation& e = loops.evaluation;
  if (e.pose_errors > 0) {
    std::printf("  %-34s %.3f m, %.2f deg\n", "relative pose error, mean", e.translation_error_mean_m,
                e.rotation_error_mean_deg);
    std::printf("  %-34s %.3f m, %.2f deg (%zu detections with a pose)\n", "relative pose error, max",
                e.translation_error_max_m, e.rotation_error_max_deg, e.pose_errors);
  } else {
    std::printf("  %-34s - (no correct detection with a pose)\n", "relative pose error");
  }
  std::printf("  latency, median / p99 / max:\n");
  print_spread("  CAN stamp - QueryTime", loops.latency_s, 1000.0, "ms");
  print_spread("  CAN stamp - time of QueryFrame", loops.since_query_frame_s, 1000.0, "ms");
  print_spread("  CAN stamp - last frame before it", loops.processing_s, 1000.0, "ms");
  if (loops.query_time_inconsistent > 0)
    std::printf(
        "  note: %zu of %zu detections carry a QueryTime before their QueryFrame or after\n"
        "        their send time (the DBC: capture time of the frame that completed it)\n",
        loops.query_time_inconsistent, loops.outcomes.size());
}

void print_loops(const Run& r) {
  const LoopScore& loops = r.loops;
  const replay::Evaluation& e = loops.evaluation;
  std::printf("\nLoop detections (correct when the true positions are within %g m)\n", r.o.tolerance);
  std::printf("  %-34s %zu\n", "detections", loops.outcomes.size());
  std::printf("  %-34s %zu / %zu", "correct / wrong", e.correct, e.wrong);
  if (e.unjudged > 0) std::printf(" (%zu beyond frames.csv)", e.unjudged);
  std::printf("\n");
  print_wrong_loops(loops);
  std::printf("  %-34s %s\n", "precision", percent_text(e.correct, e.correct + e.wrong).c_str());
  std::printf("  %-34s %zu of %zu (%s)\n", "revisited 100 m stretches detected", e.revisit_segments_detected,
              e.revisit_segments, percent_text(e.revisit_segments_detected, e.revisit_segments).c_str());
  for (const replay::MissedStretch& m : e.missed_stretches)
    std::printf("    missed %llu..%llu m: frames %zu..%zu revisit frames %zu..%zu\n",
                (unsigned long long)(m.index * 100), (unsigned long long)((m.index + 1) * 100), m.first_frame,
                m.last_frame, m.first_visit_from, m.first_visit_to);
  print_pose_error_and_latency(loops);
}

void print_marking_classes(const MarkingScore& markings) {
  std::printf("  %-14s %8s %8s %8s %10s %10s %9s\n", "class", "visible", "found", "recall", "detections",
              "precision", "accuracy");
  for (std::size_t c = 0; c < markings.per_class.size(); ++c) {
    const ClassScore& k = markings.per_class[c];
    if (k.truth == 0 && k.detections == 0) continue;
    // Per class: recall = found with the right label / visible; precision =
    // detections of this label on a marking of this class / detections of
    // this label; accuracy = right label / found.
    std::printf("  %-14s %8zu %8zu %8s %10zu %10s %9s\n",
                std::string(perception::kMarkingClassNames[c]).c_str(), k.truth, k.truth_found,
                percent_text(k.truth_right_label, k.truth).c_str(), k.detections,
                percent_text(markings.confusion[c][c], k.detections).c_str(),
                percent_text(k.truth_right_label, k.truth_found).c_str());
  }
}

void print_markings(const Run& r) {
  if (!r.have_markings) {
    std::printf("\nMarkings: %s\n", r.marking_note.c_str());
    return;
  }
  const MarkingScore& m = r.markings;
  std::printf("\nMarkings (%s against visible.csv; match: centre inside or IoU >= %.1f)\n",
              r.o.detections.c_str(), kMinIntersectionOverUnion);
  std::printf("  %-34s %zu\n", "visible markings", m.truth);
  std::printf("  %-34s %zu\n", "detections", m.detections);
  std::printf("  %-34s %s (%zu of %zu)\n", "detection recall (any label)",
              percent_text(m.matched, m.truth).c_str(), m.matched, m.truth);
  std::printf("  %-34s %s (%zu of %zu)\n", "detection precision (any label)",
              percent_text(m.matched, m.detections).c_str(), m.matched, m.detections);
  std::printf("  %-34s %s (%zu of %zu matched)\n", "classification accuracy",
              percent_text(m.right_label, m.matched).c_str(), m.right_label, m.matched);
  print_marking_classes(m);
}

void print_table(const Run& r) {
  print_can(r);
  print_status(r.log);
  print_loops(r);
  replay::print_revisit_tally(stdout, r.revisit_tally);
  replay::print_revisit_events(stdout, r.revisits, kListedRevisits);
  print_markings(r);
  if (r.have_landmarks)
    print_landmarks(r.placed, r.landmarks, r.world);
  else
    std::printf("\nLandmarks: %s\n", r.landmark_note.c_str());
  if (r.have_passes)
    print_passes(r.passes);
  else
    std::printf("\nMarkings driven past: need the detections and the landmarks: not evaluated\n");
}

// The picture's second line: the run's figures in brief.
std::string figure_subtitle(const Run& r) {
  const replay::Evaluation& e = r.loops.evaluation;
  char text[256];
  std::string subtitle = "precision " + percent_text(e.correct, e.correct + e.wrong);
  std::snprintf(text, sizeof text, ", revisits %zu/%zu", e.revisit_segments_detected, e.revisit_segments);
  subtitle += text;
  if (e.pose_errors > 0) {
    std::snprintf(text, sizeof text, ", pose error mean %.2f m %.2f deg", e.translation_error_mean_m,
                  e.rotation_error_mean_deg);
    subtitle += text;
  }
  if (r.loops.since_query_frame_s.count > 0) {
    std::snprintf(text, sizeof text, ", query frame to CAN median %.0f ms",
                  r.loops.since_query_frame_s.median * 1000.0);
    subtitle += text;
  }
  std::snprintf(text, sizeof text, ", route %.2f km", r.length_m / 1000.0);
  return subtitle + text;
}

void draw_pictures(const Run& r) {
  FigureContent figure;
  figure.route = &r.route;
  figure.markings = &r.world;
  figure.loops = &r.loops.outcomes;
  std::vector<Pose2> corrected;
  if (!r.o.corrected.empty()) {
    corrected = or_fail(corrected_on_route(r.o.corrected, r.route, r.times));
    figure.corrected = &corrected;
  }
  char text[256];
  std::snprintf(text, sizeof text, "markloop: %zu loop detections, %zu wrong (tolerance %g m)",
                r.loops.outcomes.size(), r.loops.evaluation.wrong, r.o.tolerance);
  figure.title = text;
  figure.subtitle = figure_subtitle(r);
  if (const Status svg = write_svg(r.o.svg, figure); !svg) tools::fail_run(svg.message());
  if (const Status png = write_png(r.o.png, figure); !png) tools::fail_run(png.message());
  std::printf("\npicture: %s, %s\n", r.o.svg.c_str(), r.o.png.c_str());
}

void json_can(std::FILE* f, const EcuCanLog& log) {
  std::fprintf(f, "\"can\":{\"frames\":%llu,\"other_frames\":%llu,", (unsigned long long)log.frames,
               (unsigned long long)log.other_frames);
  json_rejects(f, "loop_detection", log.loop_frames);
  std::fputc(',', f);
  json_rejects(f, "status", log.status_frames);
  std::fprintf(f, ",\"detections_incomplete\":%llu},", (unsigned long long)log.detections_incomplete);
  const StatusSummary& s = log.status;
  std::fprintf(
      f,
      "\"status\":{\"frames_processed\":%u,\"frames_dropped\":%u,\"loop_time_max_ms\":%.2f,"
      "\"database_fill_percent\":%.1f,\"landmarks\":%u,\"sequences\":%u,\"last_state\":\"%s\","
      "\"frames_blind\":%u,\"fault_frames\":{\"camera_lost\":%llu,\"camera_blind\":%llu,"
      "\"odometry_timeout\":%llu,\"bus_error\":%llu,\"overrun\":%llu}},",
      s.last.frames_processed, s.last.frames_dropped, s.loop_time_max_ms, s.last.database_fill_percent,
      s.last.landmark_count, s.last.sequence_count, std::string(dbc::to_string(s.last.system_state)).c_str(),
      s.last.frames_blind, (unsigned long long)s.camera_lost, (unsigned long long)s.camera_blind,
      (unsigned long long)s.odometry_timeout, (unsigned long long)s.bus_error, (unsigned long long)s.overrun);
}

const char* verdict_name(Verdict v) {
  return v == Verdict::Correct ? "correct" : v == Verdict::Wrong ? "wrong" : "unjudged";
}

void json_loop_events(std::FILE* f, const LoopScore& loops) {
  const replay::Evaluation& e = loops.evaluation;
  std::fprintf(f, ",\"missed_stretches\":[");
  for (std::size_t i = 0; i < e.missed_stretches.size(); ++i) {
    const replay::MissedStretch& m = e.missed_stretches[i];
    std::fprintf(f, "%s{\"from_m\":%llu,\"to_m\":%llu,\"frames\":[%zu,%zu],\"first_visit_frames\":[%zu,%zu]}",
                 i > 0 ? "," : "", (unsigned long long)(m.index * 100),
                 (unsigned long long)((m.index + 1) * 100), m.first_frame, m.last_frame, m.first_visit_from,
                 m.first_visit_to);
  }
  std::fprintf(f, "]");
  std::fprintf(f, ",\"events\":[");
  for (std::size_t i = 0; i < loops.outcomes.size(); ++i) {
    const LoopOutcome& l = loops.outcomes[i];
    std::fprintf(f,
                 "%s{\"query_frame\":%u,\"match_frame\":%u,\"verdict\":\"%s\",\"true_distance_m\":%.3f,"
                 "\"latency_s\":%.6f",
                 i ? "," : "", l.pair.query, l.pair.match, verdict_name(l.verdict), l.true_distance_m,
                 l.latency_s);
    if (l.pose_error)
      std::fprintf(f, ",\"translation_error_m\":%.4f,\"rotation_error_deg\":%.4f",
                   l.pose_error->translation_m, l.pose_error->rotation_deg);
    std::fputc('}', f);
  }
  std::fprintf(f, "]}");
}

void json_loops(std::FILE* f, const LoopScore& loops) {
  const replay::Evaluation& e = loops.evaluation;
  std::fprintf(f,
               "\"loops\":{\"detections\":%zu,\"correct\":%zu,\"wrong\":%zu,\"unjudged\":%zu,"
               "\"revisit_segments\":%zu,\"revisit_segments_detected\":%zu,\"pose_errors\":%zu,"
               "\"translation_error_mean_m\":%.4f,\"translation_error_max_m\":%.4f,"
               "\"rotation_error_mean_deg\":%.4f,\"rotation_error_max_deg\":%.4f,"
               "\"query_time_inconsistent\":%zu,",
               loops.outcomes.size(), e.correct, e.wrong, e.unjudged, e.revisit_segments,
               e.revisit_segments_detected, e.pose_errors, e.translation_error_mean_m,
               e.translation_error_max_m, e.rotation_error_mean_deg, e.rotation_error_max_deg,
               loops.query_time_inconsistent);
  json_spread(f, "latency_s", loops.latency_s);
  std::fputc(',', f);
  json_spread(f, "processing_s", loops.processing_s);
  std::fputc(',', f);
  json_spread(f, "since_query_frame_s", loops.since_query_frame_s);
  json_loop_events(f, loops);
}

void json_markings(std::FILE* f, const MarkingScore& m) {
  std::fprintf(f,
               ",\"markings\":{\"visible\":%zu,\"detections\":%zu,\"matched\":%zu,\"right_label\":%zu,"
               "\"per_class\":{",
               m.truth, m.detections, m.matched, m.right_label);
  bool first = true;
  for (std::size_t c = 0; c < m.per_class.size(); ++c) {
    const ClassScore& k = m.per_class[c];
    if (k.truth == 0 && k.detections == 0) continue;
    std::fprintf(f,
                 "%s\"%s\":{\"visible\":%zu,\"found\":%zu,\"right_label\":%zu,\"detections\":%zu,"
                 "\"detections_matched\":%zu}",
                 first ? "" : ",", std::string(perception::kMarkingClassNames[c]).c_str(), k.truth,
                 k.truth_found, k.truth_right_label, k.detections, k.detections_matched);
    first = false;
  }
  std::fprintf(f, "},\"confusion\":[");
  for (std::size_t t = 0; t < m.confusion.size(); ++t) {
    std::fprintf(f, "%s[", t ? "," : "");
    for (std::size_t d = 0; d < m.confusion[t].size(); ++d)
      std::fprintf(f, "%s%zu", d ? "," : "", m.confusion[t][d]);
    std::fputc(']', f);
  }
  std::fprintf(f, "]}");
}

void json_landmarks(std::FILE* f, const LandmarkScore& l, const std::vector<LandmarkRecord>& landmarks,
                    const std::vector<WorldMarking>& world) {
  std::fprintf(f,
               ",\"landmarks\":{\"count\":%zu,\"without_pose\":%zu,\"right_label\":%zu,\"wrong_label\":%zu,"
               "\"on_nothing\":%zu,",
               l.landmarks, l.without_pose, l.right_label, l.wrong_label, l.on_nothing);
  json_spread(f, "distance_m", l.distance_m);
  std::fprintf(f, ",\"misplaced\":[");
  for (std::size_t i = 0; i < l.misplaced.size(); ++i) {
    const MisplacedLandmark& m = l.misplaced[i];
    const LandmarkRecord& r = landmarks[m.landmark];
    std::fprintf(
        f, "%s{\"landmark\":%zu,\"label\":\"%s\",\"frames\":[%u,%u],\"at\":[%.3f,%.3f],\"judged\":\"%s\"",
        i ? "," : "", m.landmark + 1, class_name(r.label).c_str(), r.first_frame, r.last_frame, m.x, m.y,
        misplacement(l, m));
    if (m.nearest)
      std::fprintf(f, ",\"nearest\":{\"id\":%u,\"class\":\"%s\",\"distance_m\":%.3f}", world[*m.nearest].id,
                   class_name(world[*m.nearest].label).c_str(), m.distance_m);
    std::fputc('}', f);
  }
  std::fprintf(f, "]}");
}

void json_passes(std::FILE* f, const PassScore& p) {
  std::fprintf(f, ",\"passes\":{\"count\":%zu,\"cut_by_drive_ends\":%zu", p.passes.size(),
               p.cut_by_drive_ends);
  for (std::size_t i = 0; i < kPassOutcomeCount; ++i)
    std::fprintf(f, ",\"%s\":%zu", outcome_name(static_cast<PassOutcome>(i)), p.outcomes[i]);
  std::fprintf(f, ",\"per_class\":{");
  bool first = true;
  for (std::size_t c = 0; c < p.passes_of_class.size(); ++c) {
    if (p.passes_of_class[c] == 0) continue;
    std::fprintf(f, "%s\"%s\":{\"passes\":%zu,\"named_right\":%zu}", first ? "" : ",",
                 class_name(static_cast<Label>(c)).c_str(), p.passes_of_class[c], p.named_right_of_class[c]);
    first = false;
  }
  std::fprintf(f, "},\"not_named_right\":[");
  first = true;
  for (const MarkingPass& pass : p.passes) {
    if (pass.outcome == PassOutcome::NamedRight) continue;
    std::fprintf(f, "%s{\"id\":%u,\"class\":\"%s\",\"frames\":[%u,%u],\"detections\":%zu,\"outcome\":\"%s\"",
                 first ? "" : ",", pass.id, class_name(pass.label).c_str(), pass.first_frame, pass.last_frame,
                 pass.detections, outcome_name(pass.outcome));
    if (pass.outcome == PassOutcome::NamedWrong)
      std::fprintf(f, ",\"named\":\"%s\"", class_name(pass.named).c_str());
    std::fputc('}', f);
    first = false;
  }
  std::fprintf(f, "]}");
}

// Every figure of the run as one JSON object; an error when the file cannot
// be written.
Status write_json(const std::string& path, const Run& r) {
  tools::OutputFile file;
  if (Status opened = file.open(path); !opened) return opened;
  std::FILE* f = file.get();
  std::fprintf(f, "{\"frames\":%zu,\"route_length_m\":%.1f,\"tolerance_m\":%g,", r.route.size(), r.length_m,
               r.o.tolerance);
  json_can(f, r.log);
  json_loops(f, r.loops);
  std::fputc(',', f);
  replay::json_revisits(f, r.revisits, r.revisit_tally);
  if (r.have_markings) json_markings(f, r.markings);
  if (r.have_landmarks) json_landmarks(f, r.placed, r.landmarks, r.world);
  if (r.have_passes) json_passes(f, r.passes);
  std::fprintf(f, "}\n");
  return file.close();
}

}  // namespace

// --summary: the eval.json files summed; exits.
[[noreturn]] void run_summary(const Options& o) {
  std::vector<DriveFigures> drives;
  for (const std::string& file : o.summary_files) drives.push_back(or_fail(load_drive_figures(file)));
  const DrivesSummary summary = summarise_drives(drives);
  print_drives_summary(stdout, summary);
  if (!o.json.empty()) {
    if (const Status written = write_drives_summary_json(o.json, summary); !written)
      tools::fail_run(written.message());
    std::printf("figures: %s\n", o.json.c_str());
  }
  if (const Status flushed = tools::flush_stdout(); !flushed) tools::fail_run(flushed.message());
  std::exit(kExitOk);
}

int main(int argc, char** argv) {
  program_name() = "markloop-eval";
  Run r;
  r.o = parse(argc, argv);
  if (r.o.summary) run_summary(r.o);
  check_outputs(r.o);
  load_route(r);
  r.world = or_fail(load_world_markings(std::filesystem::path(r.o.dir) / "markings.csv"));
  load_can_log(r);
  load_ecu_outputs(r);
  score(r);
  print_table(r);
  draw_pictures(r);
  if (!r.o.json.empty()) {
    if (const Status written = write_json(r.o.json, r); !written) tools::fail_run(written.message());
    std::printf("figures: %s\n", r.o.json.c_str());
  }
  if (const Status flushed = tools::flush_stdout(); !flushed) tools::fail_run(flushed.message());
  return kExitOk;
}
