// markloop-eval: judges a run of the ECU against the simulator's truth: loop
// precision and revisit recall, relative pose error, latency on the bus, and
// marking detection/classification; draws the run as SVG and PNG.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "app/common/cli.hpp"
#include "app/tools/common/tool_files.hpp"
#include "app/tools/eval/can_log.hpp"
#include "app/tools/eval/figure.hpp"
#include "app/tools/eval/inputs.hpp"
#include "app/tools/eval/scoring.hpp"
#include "app/tools/replay/paper_format.hpp"
#include "app/tools/replay/truth_judge.hpp"

namespace {

using namespace markloop;
using namespace markloop::eval;
using namespace markloop::cli;

// Same as the engine's default minimum separation: a revisit is a return to
// a place driven at least this far before (see TruthJudge).
constexpr double kRevisitSeparation_m = 100.0;

constexpr const char* kUsage = R"(usage: markloop-eval DIR [options]

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
  --help             this text

figures:
  loop precision     correct / judged LoopDetection messages
  revisit recall     revisited 100 m stretches of the route (places driven
                     again at least 100 m later) with a correct detection
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
  std::string dir, can, detections, svg, png, json;
  bool detections_given = false;
  std::string landmarks;
  bool landmarks_given = false;
  double tolerance = 5.0;
};

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    }
    if (!arg.starts_with("-")) {
      if (!o.dir.empty()) fail("more than one DIR given: '" + o.dir + "' and '" + std::string(arg) + "'");
      o.dir = arg;
      continue;
    }
    const char* v = option_value(
        argc, argv, i, {"--can", "--detections", "--landmarks", "--tolerance", "--svg", "--png", "--json"});
    if (arg == "--can")
      o.can = v;
    else if (arg == "--detections")
      o.detections = v, o.detections_given = true;
    else if (arg == "--landmarks")
      o.landmarks = v, o.landmarks_given = true;
    else if (arg == "--tolerance")
      o.tolerance = parse_number(arg, v);
    else if (arg == "--svg")
      o.svg = v;
    else if (arg == "--png")
      o.png = v;
    else if (arg == "--json")
      o.json = v;
  }
  if (o.dir.empty()) fail("DIR is required (see --help)");
  if (!(o.tolerance > 0 && o.tolerance <= 10000)) fail("--tolerance must be in (0, 10000] metres");
  const std::filesystem::path dir(o.dir);
  if (o.can.empty()) o.can = dir / "ecu-can.log";
  if (o.detections.empty()) o.detections = dir / "ecu-detections.csv";
  if (o.landmarks.empty()) o.landmarks = dir / "ecu-landmarks.csv";
  if (o.svg.empty()) o.svg = dir / "loops.svg";
  if (o.png.empty()) o.png = dir / "loops.png";
  return o;
}

// An output that is one of the inputs would destroy it: refused before the run.
void check_outputs(const Options& o) {
  const std::filesystem::path dir(o.dir);
  const std::string inputs[] = {dir / "frames.csv", dir / "markings.csv", dir / "visible.csv", o.can,
                                o.detections,       o.landmarks};
  for (const std::string* output : {&o.svg, &o.png, &o.json})
    for (const std::string& input : inputs)
      if (!output->empty() && tools::overwrites(*output, input))
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

// Returns false with `error` when the file cannot be written.
bool write_json(const std::string& path, const Options& o, std::size_t frames, double length_m,
                const EcuCanLog& log, const LoopScore& loops, const MarkingScore* markings,
                const LandmarkScore* landmarks, const std::vector<LandmarkRecord>& landmark_records,
                const std::vector<WorldMarking>& world, const PassScore* passes, std::string& error) {
  tools::OutputFile file;
  if (!file.open(path, error)) return false;
  std::FILE* f = file.get();
  const replay::Evaluation& e = loops.evaluation;
  std::fprintf(f, "{\"frames\":%zu,\"route_length_m\":%.1f,\"tolerance_m\":%g,", frames, length_m,
               o.tolerance);
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
                 i ? "," : "", l.pair.query, l.pair.match,
                 l.verdict == Verdict::Correct ? "correct"
                 : l.verdict == Verdict::Wrong ? "wrong"
                                               : "unjudged",
                 l.true_distance_m, l.latency_s);
    if (l.pose_error)
      std::fprintf(f, ",\"translation_error_m\":%.4f,\"rotation_error_deg\":%.4f",
                   l.pose_error->translation_m, l.pose_error->rotation_deg);
    std::fputc('}', f);
  }
  std::fprintf(f, "]}");
  if (markings != nullptr) {
    const MarkingScore& m = *markings;
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
  if (landmarks != nullptr) {
    const LandmarkScore& l = *landmarks;
    std::fprintf(f,
                 ",\"landmarks\":{\"count\":%zu,\"without_pose\":%zu,\"right_label\":%zu,\"wrong_label\":%zu,"
                 "\"on_nothing\":%zu,",
                 l.landmarks, l.without_pose, l.right_label, l.wrong_label, l.on_nothing);
    json_spread(f, "distance_m", l.distance_m);
    std::fprintf(f, ",\"misplaced\":[");
    for (std::size_t i = 0; i < l.misplaced.size(); ++i) {
      const MisplacedLandmark& m = l.misplaced[i];
      const LandmarkRecord& r = landmark_records[m.landmark];
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
  if (passes != nullptr) {
    const PassScore& p = *passes;
    std::fprintf(f, ",\"passes\":{\"count\":%zu,\"cut_by_drive_ends\":%zu", p.passes.size(),
                 p.cut_by_drive_ends);
    for (std::size_t i = 0; i < kPassOutcomeCount; ++i)
      std::fprintf(f, ",\"%s\":%zu", outcome_name(static_cast<PassOutcome>(i)), p.outcomes[i]);
    std::fprintf(f, ",\"per_class\":{");
    bool first = true;
    for (std::size_t c = 0; c < p.passes_of_class.size(); ++c) {
      if (p.passes_of_class[c] == 0) continue;
      std::fprintf(f, "%s\"%s\":{\"passes\":%zu,\"named_right\":%zu}", first ? "" : ",",
                   class_name(static_cast<Label>(c)).c_str(), p.passes_of_class[c],
                   p.named_right_of_class[c]);
      first = false;
    }
    std::fprintf(f, "},\"not_named_right\":[");
    first = true;
    for (const MarkingPass& pass : p.passes) {
      if (pass.outcome == PassOutcome::NamedRight) continue;
      std::fprintf(f,
                   "%s{\"id\":%u,\"class\":\"%s\",\"frames\":[%u,%u],\"detections\":%zu,\"outcome\":\"%s\"",
                   first ? "" : ",", pass.id, class_name(pass.label).c_str(), pass.first_frame,
                   pass.last_frame, pass.detections, outcome_name(pass.outcome));
      if (pass.outcome == PassOutcome::NamedWrong)
        std::fprintf(f, ",\"named\":\"%s\"", class_name(pass.named).c_str());
      std::fputc('}', f);
      first = false;
    }
    std::fprintf(f, "]}");
  }
  std::fprintf(f, "}\n");
  return file.close(error);
}

}  // namespace

int main(int argc, char** argv) {
  program_name() = "markloop-eval";
  const Options o = parse(argc, argv);
  check_outputs(o);
  const std::filesystem::path dir(o.dir);
  std::string error;

  // Truth: frames.csv must be the simulator's, with its header (KITTI poses
  // carry no times).
  const std::string frames_path = dir / "frames.csv";
  std::vector<Pose2> route;
  std::vector<double> times;
  if (!replay::load_frames_csv(frames_path, route, times, error)) fail(error);
  if (route.empty()) fail(frames_path + ": no frames");
  for (std::size_t i = 1; i < times.size(); ++i)
    if (!(times[i] > times[i - 1]))
      fail(frames_path + ":" + std::to_string(i + 2) + ": time does not increase");

  std::vector<WorldMarking> world;
  if (!load_world_markings(dir / "markings.csv", world, error)) fail(error);

  // The log's stamps must be the drive's clock (frames.csv's times).
  const DriveTimes drive{times.empty() ? 0.0 : times.front(), times.empty() ? 0.0 : times.back()};
  EcuCanLog log;
  if (!read_ecu_can_log(o.can, log, error, times.empty() ? nullptr : &drive)) fail(error);
  for (const std::string& warning : can_log_warnings(o.can, log))
    std::fprintf(stderr, "%s: warning: %s\n", program_name(), warning.c_str());

  const replay::TruthJudge judge(route, o.tolerance, kRevisitSeparation_m);
  const LoopScore loops = score_loops(judge, times, log.loops);

  std::vector<VisibleMarking> visible;
  std::vector<DetectionRecord> detections;
  std::string marking_note;
  bool have_markings = false;
  if (!o.detections_given && !std::filesystem::exists(o.detections)) {
    marking_note = o.detections + " not found: marking detection not evaluated";
  } else {
    if (!load_detections(o.detections, route.size(), detections, error)) fail(error);
    if (!load_visible(dir / "visible.csv", route.size(), visible, error)) fail(error);
    have_markings = true;
  }
  const MarkingScore markings = have_markings ? score_markings(visible, detections) : MarkingScore{};
  std::vector<LandmarkRecord> landmarks;
  std::string landmark_note;
  bool have_landmarks = false;
  if (!o.landmarks_given && !std::filesystem::exists(o.landmarks)) {
    landmark_note = o.landmarks + " not found: landmarks not evaluated";
  } else {
    if (!load_landmarks(o.landmarks, route.size(), landmarks, error)) fail(error);
    have_landmarks = true;
  }
  const LandmarkScore placed = have_landmarks ? score_landmarks(world, route, landmarks) : LandmarkScore{};
  // A pass's detections are told with it: it needs both files.
  const bool have_passes = have_landmarks && have_markings;
  const PassScore passes =
      have_passes ? score_passes(world, route, times, visible, detections, markings, landmarks, placed)
                  : PassScore{};

  // --- table ---
  const double length_m = route_length_m(route);
  const replay::Evaluation& e = loops.evaluation;
  std::printf("markloop-eval: %s: %zu frames (%.1f s), route %.2f km, %zu markings in the world\n",
              o.dir.c_str(), route.size(), times.back() - times.front(), length_m / 1000.0, world.size());
  std::printf("\nCAN output %s: %llu frames\n", o.can.c_str(), (unsigned long long)log.frames);
  print_rejects("LoopDetection", log.loop_frames);
  print_rejects("Status", log.status_frames);
  if (log.other_frames > 0) std::printf("  %-14s %8llu\n", "other ids", (unsigned long long)log.other_frames);
  std::printf("  %-14s %8zu complete, %llu incomplete (a page missing or rejected)\n", "detections",
              log.loops.size(), (unsigned long long)log.detections_incomplete);

  const StatusSummary& s = log.status;
  if (log.status_frames.accepted > 0) {
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
    std::printf(
        "  %-34s camera lost %llu, camera blind %llu, odometry timeout %llu, bus error %llu, "
        "overrun %llu\n",
        "Status frames with a fault", (unsigned long long)s.camera_lost, (unsigned long long)s.camera_blind,
        (unsigned long long)s.odometry_timeout, (unsigned long long)s.bus_error,
        (unsigned long long)s.overrun);
  }

  std::printf("\nLoop detections (correct when the true positions are within %g m)\n", o.tolerance);
  std::printf("  %-34s %zu\n", "detections", loops.outcomes.size());
  std::printf("  %-34s %zu / %zu", "correct / wrong", e.correct, e.wrong);
  if (e.unjudged > 0) std::printf(" (%zu beyond frames.csv)", e.unjudged);
  std::printf("\n");
  for (const LoopOutcome& l : loops.outcomes) {
    if (l.verdict != Verdict::Wrong) continue;
    std::printf("    wrong: frame %u against frame %u, %.1f m apart", l.pair.query, l.pair.match,
                l.true_distance_m);
    if (l.pose_error)
      std::printf(" (relative pose error %.3f m, %.2f deg)", l.pose_error->translation_m,
                  l.pose_error->rotation_deg);
    std::printf("\n");
  }
  std::printf("  %-34s %s\n", "precision", percent_text(e.correct, e.correct + e.wrong).c_str());
  std::printf("  %-34s %zu of %zu (%s)\n", "revisited 100 m stretches detected", e.revisit_segments_detected,
              e.revisit_segments, percent_text(e.revisit_segments_detected, e.revisit_segments).c_str());
  for (const replay::MissedStretch& m : e.missed_stretches)
    std::printf("    missed %llu..%llu m: frames %zu..%zu revisit frames %zu..%zu\n",
                (unsigned long long)(m.index * 100), (unsigned long long)((m.index + 1) * 100), m.first_frame,
                m.last_frame, m.first_visit_from, m.first_visit_to);
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

  if (have_markings) {
    std::printf("\nMarkings (%s against visible.csv; match: centre inside or IoU >= %.1f)\n",
                o.detections.c_str(), kMinIntersectionOverUnion);
    std::printf("  %-34s %zu\n", "visible markings", markings.truth);
    std::printf("  %-34s %zu\n", "detections", markings.detections);
    std::printf("  %-34s %s (%zu of %zu)\n", "detection recall (any label)",
                percent_text(markings.matched, markings.truth).c_str(), markings.matched, markings.truth);
    std::printf("  %-34s %s (%zu of %zu)\n", "detection precision (any label)",
                percent_text(markings.matched, markings.detections).c_str(), markings.matched,
                markings.detections);
    std::printf("  %-34s %s (%zu of %zu matched)\n", "classification accuracy",
                percent_text(markings.right_label, markings.matched).c_str(), markings.right_label,
                markings.matched);
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
  } else {
    std::printf("\nMarkings: %s\n", marking_note.c_str());
  }
  if (have_landmarks)
    print_landmarks(placed, landmarks, world);
  else
    std::printf("\nLandmarks: %s\n", landmark_note.c_str());
  if (have_passes)
    print_passes(passes);
  else
    std::printf("\nMarkings driven past: need the detections and the landmarks: not evaluated\n");

  // --- picture ---
  FigureContent figure;
  figure.route = &route;
  figure.markings = &world;
  figure.loops = &loops.outcomes;
  char text[256];
  std::snprintf(text, sizeof text, "markloop: %zu loop detections, %zu wrong (tolerance %g m)",
                loops.outcomes.size(), e.wrong, o.tolerance);
  figure.title = text;
  std::string subtitle = "precision " + percent_text(e.correct, e.correct + e.wrong);
  std::snprintf(text, sizeof text, ", revisits %zu/%zu", e.revisit_segments_detected, e.revisit_segments);
  subtitle += text;
  if (e.pose_errors > 0) {
    std::snprintf(text, sizeof text, ", pose error mean %.2f m %.2f deg", e.translation_error_mean_m,
                  e.rotation_error_mean_deg);
    subtitle += text;
  }
  if (loops.since_query_frame_s.count > 0) {
    std::snprintf(text, sizeof text, ", query frame to CAN median %.0f ms",
                  loops.since_query_frame_s.median * 1000.0);
    subtitle += text;
  }
  std::snprintf(text, sizeof text, ", route %.2f km", length_m / 1000.0);
  subtitle += text;
  figure.subtitle = subtitle;
  if (!write_svg(o.svg, figure, error)) tools::fail_run(error);
  if (!write_png(o.png, figure, error)) tools::fail_run(error);
  std::printf("\npicture: %s, %s\n", o.svg.c_str(), o.png.c_str());
  if (!o.json.empty()) {
    if (!write_json(o.json, o, route.size(), length_m, log, loops, have_markings ? &markings : nullptr,
                    have_landmarks ? &placed : nullptr, landmarks, world, have_passes ? &passes : nullptr,
                    error))
      tools::fail_run(error);
    std::printf("figures: %s\n", o.json.c_str());
  }
  if (!tools::flush_stdout(error)) tools::fail_run(error);
  return 0;
}
