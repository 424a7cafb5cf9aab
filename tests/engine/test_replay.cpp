// markloop-replay's core: input files read within their limits, frames fed
// in time that follows the records (not the frame numbers) with the same
// matches as every frame fed, and truth judged in time that follows the
// truth's frames (not its length in metres).
#include <catch2/catch_test_macros.hpp>
#include <catch2/matchers/catch_matchers_string.hpp>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "app/tools/common/tool_files.hpp"
#include "app/tools/replay/paper_format.hpp"
#include "app/tools/replay/replay.hpp"
#include "app/tools/replay/truth_judge.hpp"
#include "sim/drive.hpp"
#include "sim/world.hpp"
#include "tests/support/result_checks.hpp"

using namespace markloop;
using namespace markloop::replay;
using Catch::Matchers::ContainsSubstring;
using markloop::test::error_of;
using markloop::test::loaded;

namespace {

std::filesystem::path scratch() {
  const auto dir = std::filesystem::temp_directory_path() / "markloop-replay-tests";
  std::filesystem::create_directories(dir);
  return dir;
}

std::string write_temp(const std::string& name, const std::string& content) {
  const auto path = scratch() / name;
  std::ofstream(path) << content;
  return path.string();
}

// A sparse file of `bytes` (nothing written): over a limit without filling a disk.
std::string sparse_file(const std::string& name, std::uintmax_t bytes) {
  const auto path = scratch() / name;
  std::ofstream(path).close();
  std::filesystem::resize_file(path, bytes);
  return path.string();
}

// The records and poses a simulated drive's markings.txt and poses.txt hold.
void simulated_drive(std::vector<MarkingRecord>& records, std::vector<Pose2>& poses) {
  const auto scenario = sim::make_scenario("loop", 2);
  sim::Drive drive(*scenario, sim::DriveConfig{}, 7);
  const auto& names = sim::marking_class_names();
  sim::DriveFrame frame;
  while (drive.next(frame)) {
    poses.push_back(frame.estimate.pose);
    for (const Observation& o : frame.observations)
      records.push_back(
          {static_cast<std::int32_t>(frame.estimate.frame), -o.y, 1.5f, o.x, names.at(o.label), 0});
  }
}

class Collect final : public MatchSink {
 public:
  void on_match(const MatchEvent& e) override { events.push_back(e); }
  std::vector<MatchEvent> events;
};

// Every frame from 0 to the last fed to the engine, as markloop-replay once
// did: the reference the sparse feeding must agree with.
std::vector<MatchEvent> every_frame(const std::vector<MarkingRecord>& records,
                                    const std::vector<Pose2>& poses, const EngineConfig& config, double fps,
                                    EngineCounters& counters) {
  std::vector<const MarkingRecord*> ordered;
  for (const MarkingRecord& r : records) ordered.push_back(&r);
  std::stable_sort(ordered.begin(), ordered.end(),
                   [](const MarkingRecord* a, const MarkingRecord* b) { return a->frame < b->frame; });
  std::size_t frames = poses.size();
  if (!ordered.empty()) frames = std::max<std::size_t>(frames, ordered.back()->frame + 1u);
  LabelTable labels;
  auto engine = std::make_unique<SequenceEngine>(config);
  Collect sink;
  std::vector<Observation> observations;
  std::size_t next = 0;
  for (std::size_t f = 0; f < frames; ++f) {
    observations.clear();
    for (; next < ordered.size() && ordered[next]->frame == static_cast<std::int32_t>(f); ++next)
      observations.push_back(to_ground(*ordered[next], labels.intern(ordered[next]->label)));
    const FrameInput input{static_cast<FrameIndex>(f), static_cast<double>(f) / fps, f < poses.size(),
                           f < poses.size() ? poses[f] : Pose2{}};
    engine->process_frame(input, observations, sink);
  }
  engine->flush(sink);
  counters = engine->counters();
  return sink.events;
}

void check_same_matches(const std::vector<MarkingRecord>& records, const std::vector<Pose2>& poses,
                        const EngineConfig& config, double fps) {
  EngineCounters reference_counters;
  const auto reference = every_frame(records, poses, config, fps, reference_counters);
  LabelTable labels;
  const ReplayResult result = run_engine(records, poses, labels, config, fps);
  CHECK(result.counters.landmarks_released == reference_counters.landmarks_released);
  CHECK(result.counters.sequences_created == reference_counters.sequences_created);
  CHECK(result.counters.queries == reference_counters.queries);
  CHECK(result.counters.candidates == reference_counters.candidates);
  REQUIRE(result.matches.size() == reference.size());
  for (std::size_t i = 0; i < reference.size(); ++i) {
    CHECK(result.matches[i].query_frame() == reference[i].query_frame());
    CHECK(result.matches[i].match_frame() == reference[i].match_frame());
    CHECK(result.matches[i].residual_m == reference[i].residual_m);
  }
}

}  // namespace

TEST_CASE("replay: frames without records are skipped with the same matches", "[replay]") {
  std::vector<MarkingRecord> records;
  std::vector<Pose2> poses;
  simulated_drive(records, poses);
  EngineConfig config;
  SECTION("no poses") {
    check_same_matches(records, {}, config, 10.0);
  }
  SECTION("no poses, gaps of several seconds between the records") {
    for (MarkingRecord& r : records) r.frame += 37 * (r.frame / 90);
    check_same_matches(records, {}, config, 10.0);
  }
  SECTION("no poses, frames spread out, other commit delay and rate") {
    for (MarkingRecord& r : records) r.frame *= 7;
    config.tracker.commit_after_s = 0.05;
    check_same_matches(records, {}, config, 30.0);
  }
  SECTION("poses for the first half of the frames only") {
    poses.resize(poses.size() / 2);
    check_same_matches(records, poses, config, 10.0);
  }
  SECTION("poses for every frame") {
    check_same_matches(records, poses, config, 10.0);
  }
}

TEST_CASE("replay: a record at the largest frame number takes no longer than the others", "[replay]") {
  const std::vector<MarkingRecord> records{{0, 1, 1.5f, 10, "A", 2}, {2147483647, 1, 1.5f, 10, "A", 3}};
  LabelTable labels;
  const auto start = std::chrono::steady_clock::now();
  const ReplayResult result = run_engine(records, {}, labels, EngineConfig{}, 10.0);
  CHECK(std::chrono::steady_clock::now() - start < std::chrono::seconds(2));
  CHECK(result.frames == 2147483648u);
  CHECK(result.matches.empty());
}

TEST_CASE("replay: inputs over their limit or not files are refused before they are read", "[replay]") {
  std::string error;
  const std::string dir = scratch().string();
  error = error_of(load_markings(dir));
  CHECK(error == dir + ": is a directory, not a markings file");
  error = error_of(load_kitti_poses(dir));
  CHECK(error == dir + ": is a directory, not a poses file");
  error = error_of(load_truth(dir));
  CHECK(error == dir + ": is a directory, not a ground truth file");

  const auto huge = sparse_file("huge.txt", kMaxMarkingsBytes + 1);
  error = error_of(load_markings(huge));
  CHECK(error == huge + ": larger than 256 MiB, the limit for a markings file");
  error = error_of(load_kitti_poses(huge));
  CHECK(error == huge + ": larger than 256 MiB, the limit for a poses file");
  error = error_of(load_frames_csv(huge));
  CHECK(error == huge + ": larger than 256 MiB, the limit for a frames.csv file");
  std::filesystem::remove(huge);

  // A device that never ends stops at the limit.
  error = error_of(load_markings("/dev/zero"));
  CHECK(error == "/dev/zero: larger than 256 MiB, the limit for a markings file");
}

TEST_CASE("replay: a declared record count reserves no more than the file holds", "[replay]") {
  // Room for the declared count (about 100 GB) would not be had: the load
  // ends on the missing records, not on the memory.
  const std::string error = error_of(load_markings(write_temp("many.txt", "2000000000\n0 1 2 3 A\n")));
  CHECK_THAT(error, ContainsSubstring("declares 2000000000 records"));
}

TEST_CASE("replay: poses far beyond any road are refused with their line", "[replay]") {
  std::string error;
  const auto far = write_temp("far.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 1e12\n");
  error = error_of(load_kitti_poses(far));
  CHECK_THAT(error, ContainsSubstring(far + ":2: position (1e+12, 0) m lies beyond 100000 km"));
  const auto csv = write_temp("far.csv", "frame,t,x,y,yaw\n0,0,0,0,0\n1,0.1,0,-3e9,0\n");
  error = error_of(load_frames_csv(csv));
  CHECK_THAT(error, ContainsSubstring(csv + ":3: position"));
  const auto no_header = write_temp("kitti.csv", "1 0 0 0 0 1 0 0 0 0 1 0\n");
  error = error_of(load_frames_csv(no_header));
  CHECK(error == no_header + ":1: expected the header 'frame,t,x,y,yaw'");
}

TEST_CASE("replay: truth judged in time that follows its frames, not its length", "[replay]") {
  // A long stay at one spot, then a car jumping between two spots 10^5 km
  // apart: every frame revisits the spot of two frames before, each in its
  // own 100 m stretch of a drive of 10^9 km.
  constexpr int kParked = 50000, kJumps = 10000;
  std::vector<Pose2> truth(kParked, Pose2{-1000.0, 0.0, 0.0});
  for (int i = 0; i < kJumps; ++i) truth.push_back({i % 2 == 0 ? 0.0 : 1e8, 0.0, 0.0});
  const auto start = std::chrono::steady_clock::now();
  const TruthJudge judge(truth, 10.0, 100.0);
  const FrameIndex first = kParked;
  const Evaluation e = judge.evaluate({{first + 4, first}});
  CHECK(std::chrono::steady_clock::now() - start < std::chrono::seconds(2));
  CHECK(e.correct == 1);
  CHECK(e.revisit_segments == kJumps - 2);
  CHECK(e.revisit_segments_detected == 1);
  REQUIRE(e.missed_stretches.size() == kJumps - 3);
  CHECK(e.missed_stretches[0].first_frame == first + 2);
  CHECK(e.missed_stretches[0].first_visit_from == first);
  CHECK(e.missed_stretches[1].first_frame == first + 3);
  CHECK(e.missed_stretches[1].first_visit_to == first + 1);
}

TEST_CASE("replay: lines of a text in memory, numbered as an editor numbers them", "[replay]") {
  tools::Lines lines("a\r\n\nb\nlast");
  std::string_view line;
  std::vector<std::string> seen;
  while (lines.next(line)) seen.emplace_back(line);
  CHECK(seen == std::vector<std::string>{"a", "", "b", "last"});
  CHECK(lines.number() == 4);
  tools::Lines empty("");
  CHECK_FALSE(empty.next(line));
  tools::Lines one("x\n");
  CHECK(one.next(line));
  CHECK_FALSE(one.next(line));
}

TEST_CASE("replay: an output is told from the input it would overwrite", "[replay]") {
  const auto input = write_temp("input.txt", "1\n0 1 2 3 A\n");
  const auto link = (scratch() / "link.txt").string();
  std::filesystem::remove(link);
  std::filesystem::create_symlink(input, link);
  CHECK(platform::overwrites(link, input));
  CHECK(platform::overwrites(input, input));
  CHECK_FALSE(platform::overwrites(write_temp("other.txt", "x"), input));
  CHECK_FALSE(platform::overwrites((scratch() / "absent.txt").string(), input));
  CHECK_FALSE(platform::overwrites("/dev/null", "/dev/null"));  // not a regular file: nothing to lose
}
