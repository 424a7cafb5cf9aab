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

#include "cli/cli.hpp"
#include "cli/memory_check.hpp"
#include "cli/tool_files.hpp"
#include "replay/compat.hpp"
#include "replay/paper_format.hpp"
#include "replay/replay.hpp"

namespace {

using namespace markloop;
using namespace markloop::replay;
using namespace markloop::cli;

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

constexpr const char* kUsage = R"(usage: markloop-replay --markings FILE [options]

Runs the online road-marking sequence engine on recorded detections and
prints the loops / places it found.

input:
  --markings FILE        detections, road_marking_centroids_3Dposition.txt
                         format: the record count, then "frame x y z label"
                         per record (y points down; the ground is x-z)
  --poses FILE           one camera pose per frame (KITTI 3x4 [R|t]); the
                         source of travelled distance. Without it, distance
                         is measured along the markings themselves
  --fps HZ               frame rate, for time, up to 1000000; default 10

engine:
  --k N                  sequence length; default 4
  --abs-tol M            distance tolerance, absolute part; default 0.5
  --rel-tol R            distance tolerance, relative part; default 0.02
  --min-separation M     a match lies at least this far back; default 100
  --min-separation-s S   ... and at least this long ago; default 10
  --max-residual M       largest RMS residual of the rigid fit; default 0.5
  --association-radius M observations of one marking lie this close; default 1.5
  --commit-after S       a marking unseen this long has left view; default 0.5
  --min-observations N   detections needed to make a landmark; default 2
  --skip-rows N          rows a sequence may step over, 0 or 1; default 1
  --sequence-capacity N  database size in sequences; default 1048576
  --landmark-capacity N  database size in landmarks; default 262144

  --compat               run the authors' batch program instead: frame gap
                         T = 30, match gap 100 T, distance tolerance 2 m, same
                         matches in the same order (only --k applies); a long
                         run reports its progress on stderr unless --quiet

output:
  --out FILE             matches in the authors' image_matches.txt format
  --jsonl FILE           one JSON record per match, with poses and residuals
  --truth FILE           ground truth (simulator frames.csv or KITTI poses):
                         report correct and wrong matches, revisit recall and
                         relative pose error
  --truth-radius M       a match is correct when the two frames' true
                         positions are this close, up to 10000; default 10
  --sweep A..B           run k = A..B and print a table of matches (and, with
                         --truth, the share of correct ones)
  --quiet                print only the summary
  --help                 this text

Input files are read whole: --markings, --poses and --truth may hold up to
256 MiB each. --poses and --truth must hold a pose for every frame the
markings use. An output may not be one of the input files.

Exit status: 0 on success; 1 when an output cannot be written; 2 on bad
options or input, or a database larger than the memory available.
)";

struct Options {
  std::string markings, poses, out, jsonl, truth;
  double fps = 10.0;
  double truth_radius = 10.0;
  bool compat = false;
  bool quiet = false;
  unsigned sweep_first = 0, sweep_last = 0;
  EngineConfig engine;
};

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    }
    if (arg == "--compat") { o.compat = true; continue; }
    if (arg == "--quiet") { o.quiet = true; continue; }
    const char* v = option_value(
        argc, argv, i,
        {"--markings", "--poses", "--out", "--jsonl", "--truth", "--fps", "--truth-radius", "--k",
         "--abs-tol", "--rel-tol", "--min-separation", "--min-separation-s", "--max-residual",
         "--association-radius", "--commit-after", "--min-observations", "--skip-rows",
         "--sequence-capacity", "--landmark-capacity", "--sweep"});
    if (arg == "--markings") o.markings = v;
    else if (arg == "--poses") o.poses = v;
    else if (arg == "--out") o.out = v;
    else if (arg == "--jsonl") o.jsonl = v;
    else if (arg == "--truth") o.truth = v;
    else if (arg == "--fps") o.fps = parse_number(arg, v);
    else if (arg == "--truth-radius") o.truth_radius = parse_number(arg, v);
    else if (arg == "--k") o.engine.chain.k = parse_whole(arg, v);
    else if (arg == "--abs-tol") o.engine.match.distance_tolerance_abs_m = parse_number(arg, v);
    else if (arg == "--rel-tol") o.engine.match.distance_tolerance_rel = parse_number(arg, v);
    else if (arg == "--min-separation") o.engine.match.min_separation_m = parse_number(arg, v);
    else if (arg == "--min-separation-s") o.engine.match.min_separation_s = parse_number(arg, v);
    else if (arg == "--max-residual") o.engine.match.max_residual_m = parse_number(arg, v);
    else if (arg == "--association-radius") o.engine.tracker.association_radius_m = parse_number(arg, v);
    else if (arg == "--commit-after") o.engine.tracker.commit_after_s = parse_number(arg, v);
    else if (arg == "--min-observations") o.engine.tracker.min_observations = parse_whole(arg, v);
    else if (arg == "--skip-rows") o.engine.chain.max_skipped_rows = parse_whole(arg, v);
    else if (arg == "--sequence-capacity") o.engine.database.sequence_capacity = parse_whole(arg, v);
    else if (arg == "--landmark-capacity") o.engine.database.landmark_capacity = parse_whole(arg, v);
    else if (arg == "--sweep") {
      const std::string text = v;
      const auto dots = text.find("..");
      if (dots == std::string::npos) fail("--sweep: expected A..B, found '" + text + "'");
      o.sweep_first = parse_whole(arg, text.substr(0, dots).c_str());
      o.sweep_last = parse_whole(arg, text.substr(dots + 2).c_str());
      if (o.sweep_first < 2 || o.sweep_last > kMaxSequenceLength || o.sweep_first > o.sweep_last)
        fail("--sweep: expected 2 <= A <= B <= 10, found '" + text + "'");
    }
  }
  if (o.markings.empty()) fail("--markings FILE is required (see --help)");
  if (!(o.fps > 0 && o.fps <= 1e6)) fail("--fps must be in (0, 1000000]");
  if (!(o.truth_radius > 0 && o.truth_radius <= 10000)) fail("--truth-radius must be in (0, 10000] metres");
  if (const char* problem = validate(o.engine)) fail(problem);
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
               label_list.c_str(), positions(e.query).c_str(), positions(e.match).c_str(),
               e.alignment.x, e.alignment.y, e.alignment.yaw * kDegPerRad);
  if (e.has_relative_pose)
    std::fprintf(f, "\"relative_pose\":{\"dx\":%.4f,\"dy\":%.4f,\"dyaw_deg\":%.3f},",
                 e.relative_pose.x, e.relative_pose.y, e.relative_pose.yaw * kDegPerRad);
  std::fprintf(f, "\"residual_m\":%.4f,\"score\":%.4f,\"verified_candidates\":%u", e.residual_m,
               e.score, e.verified_candidates);
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
    if (p.searched > 0)
      std::fprintf(stderr, ", %zu / %zu complete ones searched", p.searched, p.complete);
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

// Poses (the odometry) and truth (the judge) are per frame: a file that
// stops short of the markings' frames would leave frames unseen unnoticed.
void check_covers(const std::string& path, std::size_t count, const char* what, const Options& o,
                  const std::vector<MarkingRecord>& records) {
  const MarkingRecord* last = last_frame_record(records);
  if (count == 0 && last == nullptr) fail(path + ": has no " + what + "s");
  if (last == nullptr || count > static_cast<std::size_t>(last->frame)) return;
  fail(path + ": has " + std::to_string(count) + " " + what + (count == 1 ? "" : "s") +
       ", the markings reach frame " + std::to_string(last->frame) + " (" + o.markings + ":" +
       std::to_string(last->line) + "; one " + what + " per frame, line i for frame i)");
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
  const std::pair<const char*, const std::string*> inputs[] = {
      {"--markings", &o.markings}, {"--poses", &o.poses}, {"--truth", &o.truth}};
  for (const std::string* output : {&o.out, &o.jsonl})
    for (const auto& [option, input] : inputs)
      if (!output->empty() && !input->empty() && tools::overwrites(*output, *input))
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

int replay_main(int argc, char** argv) {
  const Options o = parse(argc, argv);
  check_outputs(o);
  std::string error;
  std::vector<MarkingRecord> records;
  if (!load_markings(o.markings, records, error)) fail(error);
  warn_unordered(o.markings, records);
  std::vector<Pose2> poses;
  if (!o.poses.empty()) {
    if (!load_kitti_poses(o.poses, poses, error)) fail(error);
    check_covers(o.poses, poses.size(), "pose", o, records);
  }
  if (!o.compat) check_database_fits(o);
  std::unique_ptr<TruthJudge> judge;
  if (!o.truth.empty()) {
    std::vector<Pose2> truth;
    if (!load_truth(o.truth, truth, error)) fail(error);
    check_covers(o.truth, truth.size(), "true pose", o, records);
    judge = std::make_unique<TruthJudge>(std::move(truth), o.truth_radius,
                                         o.engine.match.min_separation_m);
  }
  LabelTable labels;

  // One run: returns the frame pairs found, writing outputs when asked.
  const auto run = [&](unsigned k, bool write) -> std::vector<FramePair> {
    if (o.compat) {
      CompatParameters parameters;
      parameters.k = k;
      const auto matches = run_compat(records, parameters, compat_progress(o.quiet));
      if (write && !o.out.empty()) {
        tools::OutputFile f;
        if (!f.open(o.out, error)) tools::fail_run(error);
        for (std::size_t i = 0; i < matches.size(); ++i) {
          write_frames(f.get(), matches.earlier(i));
          write_frames(f.get(), matches.later(i));
        }
        if (!f.close(error)) tools::fail_run(error);
      }
      return compat_pairs(matches);
    }
    EngineConfig config = o.engine;
    config.chain.k = k;
    const ReplayResult result = run_engine(records, poses, labels, config, o.fps);
    if (write) {
      if (!o.out.empty()) {
        tools::OutputFile f;
        if (!f.open(o.out, error)) tools::fail_run(error);
        for (const MatchEvent& e : result.matches) {
          write_frames(f.get(), frames_of(e, false));
          write_frames(f.get(), frames_of(e, true));
        }
        if (!f.close(error)) tools::fail_run(error);
      }
      if (!o.jsonl.empty()) {
        tools::OutputFile f;
        if (!f.open(o.jsonl, error)) tools::fail_run(error);
        for (const MatchEvent& e : result.matches) write_jsonl(f.get(), e, labels, judge.get());
        if (!f.close(error)) tools::fail_run(error);
      }
      const auto& c = result.counters;
      std::printf("markloop-replay: %zu detections in %zu frames -> %llu landmarks, %llu sequences "
                  "of k=%u, %llu queries, %llu candidates (%llu too recent, %llu failed the rigid "
                  "fit)\n",
                  records.size(), result.frames, (unsigned long long)c.landmarks_released,
                  (unsigned long long)c.sequences_created, k, (unsigned long long)c.queries,
                  (unsigned long long)c.candidates, (unsigned long long)c.candidates_too_recent,
                  (unsigned long long)c.candidates_rejected_residual);
      if (!o.quiet) {
        for (const MatchEvent& e : result.matches) {
          std::printf("  loop: frame %u matches frame %u  [", e.query_frame(), e.match_frame());
          for (unsigned i = 0; i < e.k; ++i)
            std::printf("%s%s", i ? " " : "", labels.name(e.query[i].label).c_str());
          std::printf("]  residual %.3f m  score %.2f", e.residual_m, e.score);
          if (e.has_relative_pose)
            std::printf("  relative pose (%.2f m, %.2f m, %.1f deg)", e.relative_pose.x,
                        e.relative_pose.y, e.relative_pose.yaw * kDegPerRad);
          if (judge && judge->covers(e.query_frame()) && judge->covers(e.match_frame()) &&
              !judge->correct({e.query_frame(), e.match_frame()}))
            std::printf("  WRONG");
          std::printf("\n");
        }
      }
      std::vector<FramePair> pairs = frame_pairs(result.matches);
      std::printf("matches: %zu\n", result.matches.size());
      if (judge) print_evaluation(judge->evaluate(pairs, relative_poses(result.matches)));
      return pairs;
    }
    return frame_pairs(result.matches);
  };

  if (o.sweep_first == 0) {
    const auto pairs = run(o.engine.chain.k, true);
    if (o.compat) {
      std::printf("markloop-replay --compat: %zu records -> %zu matches (k=%u)\n", records.size(),
                  pairs.size(), o.engine.chain.k);
      if (judge) print_evaluation(judge->evaluate(pairs));
    }
    if (!tools::flush_stdout(error)) tools::fail_run(error);
    return 0;
  }

  std::printf("%-22s", "Search window size");
  for (unsigned k = o.sweep_first; k <= o.sweep_last; ++k) std::printf(" %6u", k);
  std::vector<std::size_t> counts, correct, judged;
  for (unsigned k = o.sweep_first; k <= o.sweep_last; ++k) {
    const auto pairs = run(k, false);
    counts.push_back(pairs.size());
    if (judge) {
      const Evaluation e = judge->evaluate(pairs);
      correct.push_back(e.correct);
      judged.push_back(e.correct + e.wrong);
    }
  }
  std::printf("\n%-22s", "Number of matches");
  for (const std::size_t c : counts) std::printf(" %6zu", c);
  if (judge) {
    std::printf("\n%-22s", "Correct matches (%)");
    for (std::size_t i = 0; i < counts.size(); ++i)
      judged[i] ? std::printf(" %6.1f", 100.0 * double(correct[i]) / double(judged[i])) : std::printf(" %6s", "-");
    std::printf("\n%-22s", "Incorrect matches (%)");
    for (std::size_t i = 0; i < counts.size(); ++i)
      judged[i] ? std::printf(" %6.1f", 100.0 * double(judged[i] - correct[i]) / double(judged[i])) : std::printf(" %6s", "-");
  }
  std::printf("\n");
  if (!tools::flush_stdout(error)) tools::fail_run(error);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  program_name() = "markloop-replay";
  try {
    return replay_main(argc, argv);
  } catch (const std::bad_alloc&) {
    // Inputs and the database are checked against their limits first: this
    // is what no check foresaw (another program took the memory meanwhile).
    fail("out of memory: the input or the database (--landmark-capacity, --sequence-capacity) is "
         "too large for the memory available");
  }
}
