// markloop-eval's figures on the synthetic run of eval_fixture.hpp, and its
// handling of malformed input.
#include <catch2/catch_approx.hpp>
#include <catch2/catch_test_macros.hpp>
#include <catch2/matchers/catch_matchers_string.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "app/perception/marking_classes.hpp"
#include "app/tools/eval/can_log.hpp"
#include "app/tools/eval/figure.hpp"
#include "app/tools/eval/inputs.hpp"
#include "app/tools/eval/scoring.hpp"
#include "app/tools/replay/paper_format.hpp"
#include "app/tools/replay/truth_judge.hpp"
#include "tests/eval/eval_fixture.hpp"
#include "tests/support/result_checks.hpp"

namespace fs = std::filesystem;
using namespace markloop;
using namespace markloop::eval;
using Catch::Approx;
using Catch::Matchers::StartsWith;
using markloop::test::error_of;
using markloop::test::loaded;

namespace {

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("markloop-eval-test-" + name);
  fs::remove_all(dir);
  fixture::write_run(dir);
  return dir;
}

// The CAN log at `path`, which must be read.
EcuCanLog read_log(const fs::path& path, const DriveTimes* drive = nullptr) {
  Result<EcuCanLog> log = read_ecu_can_log(path, drive);
  INFO((log ? std::string() : log.message()));
  REQUIRE(log);
  return std::move(log).value();
}

// Why the CAN log at `path` cannot be read; empty when it can.
std::string read_error(const fs::path& path, const DriveTimes* drive = nullptr) {
  const Result<EcuCanLog> log = read_ecu_can_log(path, drive);
  return log ? std::string() : log.message();
}

Label label_of(std::string_view name) {
  return *perception::marking_class_from_name(name);
}

}  // namespace

TEST_CASE("the ECU's CAN log is reassembled and its bad frames counted") {
  const fs::path dir = fresh_dir("can");
  EcuCanLog log;
  std::string error;
  log = read_log(dir / "ecu-can.log");
  constexpr std::size_t kStatusFrames = 3 * dbc::Status::kPages.size();  // three cycles
  CHECK(log.frames == 19 + kStatusFrames);
  CHECK(log.other_frames == 1);
  CHECK(log.loop_frames.accepted == 16);
  CHECK(log.loop_frames.bad_crc == 1);
  CHECK(log.loop_frames.bad_counter == 1);  // the page after the lost one
  CHECK(log.loop_frames.rejected() == 2);
  CHECK(log.detections_started == 3);
  CHECK(log.detections_incomplete == 1);
  REQUIRE(log.loops.size() == 2);
  CHECK(log.loops[0].message.query_frame == 553);
  CHECK(log.loops[0].message.match_frame == 150);
  CHECK(log.loops[0].message.pose_dy_m == Approx(0.4));
  CHECK(log.loops[0].stamp_ns == 57'004'005'000);
  CHECK(log.loops[1].message.match_id == 1);
  CHECK(log.status_frames.accepted == kStatusFrames);
  CHECK(log.status_frames.rejected() == 0);
  CHECK(log.status.last.frames_processed == 800);
  CHECK(log.status.loop_time_max_ms == Approx(12.5));
  CHECK(log.status.overrun == dbc::Status::kPages.size());  // the one cycle with an overrun
  CHECK(log.status.camera_lost == 0);
  CHECK(log.status.frames_in_state[static_cast<std::size_t>(dbc::SystemState::Running)] == kStatusFrames);
}

namespace {

// The truth and the ECU's CAN log of the fixture's run.
struct LoopDrive {
  std::vector<Pose2> route;
  std::vector<double> times;
  EcuCanLog log;
};

LoopDrive load_loop_drive(const fs::path& dir) {
  LoopDrive drive;
  {
    auto truth = loaded(replay::load_truth(dir / "frames.csv"));
    drive.route = std::move(truth.poses);
    drive.times = std::move(truth.times);
  }
  REQUIRE(drive.times.size() == fixture::kFrames);
  drive.log = read_log(dir / "ecu-can.log");
  return drive;
}

// Each missed stretch comes after the one before and revisits earlier frames
// within the judge's 5 m.
void check_missed_stretches(const replay::Evaluation& e, const std::vector<Pose2>& route) {
  for (std::size_t i = 0; i < e.missed_stretches.size(); ++i) {
    const replay::MissedStretch& m = e.missed_stretches[i];
    INFO("missed stretch " << m.index);
    if (i > 0) CHECK(m.index > e.missed_stretches[i - 1].index);
    CHECK(m.first_frame <= m.last_frame);
    CHECK(m.first_visit_from <= m.first_visit_to);
    CHECK(m.first_visit_to < m.first_frame);
    bool earlier_nearby = false;
    for (std::size_t j = m.first_visit_from; j <= m.first_visit_to; ++j)
      earlier_nearby = earlier_nearby || std::hypot(route[m.first_frame].x - route[j].x,
                                                    route[m.first_frame].y - route[j].y) <= 5.0;
    CHECK(earlier_nearby);
  }
}

void check_loop_evaluation(const replay::Evaluation& e, const std::vector<Pose2>& route) {
  CHECK(e.correct == 1);
  CHECK(e.wrong == 1);
  CHECK(e.unjudged == 0);
  // Second lap (segments 4..7) plus the end of the first, which comes back
  // within 5 m of the start.
  CHECK(e.revisit_segments == 5);
  CHECK(e.revisit_segments_detected == 1);
  // The other four are listed, each with the earlier frames it revisits.
  REQUIRE(e.missed_stretches.size() == 4);
  check_missed_stretches(e, route);
  REQUIRE(e.pose_errors == 1);
  // True relative pose (3, 0, 0): the car at the query is 3 m ahead of the
  // car at the match. The reverse convention would give an error of 6 m.
  CHECK(e.translation_error_mean_m == Approx(0.4).margin(1e-6));
  CHECK(e.rotation_error_mean_deg == Approx(1.5).margin(1e-6));
  CHECK(e.translation_error_max_m == Approx(0.4).margin(1e-6));
}

void check_loop_outcomes(const LoopScore& score) {
  REQUIRE(score.outcomes.size() == 2);
  CHECK(score.outcomes[0].verdict == Verdict::Correct);
  CHECK(score.outcomes[0].true_distance_m == Approx(3.0));
  CHECK(score.outcomes[1].verdict == Verdict::Wrong);
  CHECK(score.outcomes[1].true_distance_m == Approx(std::hypot(50.0, 100.0)));
  // A wrong one's pose error is reported too (not in the means above): here
  // the estimate (1 m ahead) is as far off as the places are apart.
  REQUIRE(score.outcomes[1].pose_error.has_value());
  CHECK(score.outcomes[1].pose_error->translation_m > 100.0);
}

void check_loop_latencies(const LoopScore& score) {
  CHECK(score.latency_s.count == 2);
  CHECK(score.latency_s.median == Approx((fixture::kLatency1_s + fixture::kLatency2_s) / 2).margin(1e-9));
  CHECK(score.latency_s.p99 == Approx(fixture::kLatency1_s).margin(1e-9));
  CHECK(score.latency_s.max == Approx(fixture::kLatency1_s).margin(1e-9));
  CHECK(score.processing_s.median == Approx((0.004005 + 0.006005) / 2).margin(1e-9));
  CHECK(score.processing_s.max == Approx(0.006005).margin(1e-9));
  CHECK(score.since_query_frame_s.median == Approx(score.latency_s.median).margin(1e-9));
  CHECK(score.query_time_inconsistent == 0);
}

}  // namespace

TEST_CASE("loop detections are judged against the truth") {
  const LoopDrive drive = load_loop_drive(fresh_dir("loops"));
  const std::vector<Pose2>& route = drive.route;
  const std::vector<double>& times = drive.times;
  const EcuCanLog& log = drive.log;
  const replay::TruthJudge judge(route, 5.0, 100.0);
  const LoopScore score = score_loops(judge, times, log.loops);

  check_loop_evaluation(score.evaluation, route);
  check_loop_outcomes(score);
  check_loop_latencies(score);

  SECTION("QueryTime is the frame that completed the detection; before QueryFrame is flagged") {
    std::vector<LoopReport> reports = log.loops;
    reports[0].message.query_time_s = 57.0;  // the frame that released the detection
    LoopScore s = score_loops(judge, times, reports);
    CHECK(s.query_time_inconsistent == 0);
    CHECK(s.latency_s.min == Approx(0.004005).margin(1e-9));
    CHECK(s.since_query_frame_s.max == Approx(fixture::kLatency1_s).margin(1e-9));
    reports[0].message.query_time_s = times[reports[0].message.query_frame] - 1.0;
    s = score_loops(judge, times, reports);
    CHECK(s.query_time_inconsistent == 1);
  }

  SECTION("a tighter tolerance makes the 3 m detection wrong") {
    const replay::TruthJudge strict(route, 2.0, 100.0);
    const LoopScore s = score_loops(strict, times, log.loops);
    CHECK(s.evaluation.correct == 0);
    CHECK(s.evaluation.wrong == 2);
  }
}

TEST_CASE("order statistics use the nearest rank for p99") {
  std::vector<double> values;
  for (int i = 1; i <= 200; ++i) values.push_back(i);
  const Spread s = spread_of(values);
  CHECK(s.median == Approx(100.5));
  CHECK(s.p99 == Approx(198.0));
  CHECK(s.max == Approx(200.0));
  CHECK(spread_of({}).count == 0);
}

TEST_CASE("quad overlap: intersection over union and centre inside") {
  const Quad unit{{{0, 0}, {100, 0}, {100, 100}, {0, 100}}};
  const Quad shifted{{{50, 0}, {150, 0}, {150, 100}, {50, 100}}};
  const Quad far{{{300, 300}, {310, 300}, {310, 310}, {300, 310}}};
  const Quad reversed{{{0, 100}, {100, 100}, {100, 0}, {0, 0}}};  // other winding
  CHECK(intersection_over_union(unit, unit) == Approx(1.0));
  CHECK(intersection_over_union(unit, reversed) == Approx(1.0));
  CHECK(intersection_over_union(unit, shifted) == Approx(1.0 / 3.0));
  CHECK(intersection_over_union(unit, far) == 0.0);
  CHECK(centre_inside(far, far));
  CHECK_FALSE(centre_inside(far, unit));
  CHECK(centre_inside(shifted, unit));  // centre on the edge counts
}

TEST_CASE("marking detections are matched to visible markings one to one") {
  const fs::path dir = fresh_dir("markings");
  std::vector<VisibleMarking> visible;
  std::vector<DetectionRecord> detections;
  std::string error;
  visible = loaded(load_visible(dir / "visible.csv", fixture::kFrames));
  detections = loaded(load_detections(dir / "ecu-detections.csv", fixture::kFrames));
  const MarkingScore m = score_markings(visible, detections);
  CHECK(m.truth == 4);
  CHECK(m.detections == 5);
  CHECK(m.matched == 3);
  CHECK(m.right_label == 2);
  CHECK(m.per_class[label_of("stop")].truth_right_label == 1);
  CHECK(m.per_class[label_of("forward")].truth_found == 1);
  CHECK(m.per_class[label_of("forward")].truth_right_label == 0);
  CHECK(m.confusion[label_of("forward")][label_of("leftturn")] == 1);
  CHECK(m.per_class[label_of("crosswalk")].truth_right_label == 1);  // by IoU alone
  CHECK(m.per_class[label_of("bike")].truth_found == 0);
  CHECK(m.per_class[label_of("ped")].detections == 2);
  CHECK(m.per_class[label_of("ped")].detections_matched == 0);
  // What each visible marking was paired with, and which detections were.
  REQUIRE(m.paired_label.size() == visible.size());
  CHECK(m.paired_label[0] == label_of("stop"));
  CHECK(m.paired_label[1] == label_of("leftturn"));
  CHECK(m.paired_label[2] == label_of("crosswalk"));
  CHECK_FALSE(m.paired_label[3].has_value());
  CHECK(m.detection_paired == std::vector<bool>{true, true, false, true, false});

  SECTION("two detections on one marking: only one matches") {
    detections.push_back(detections.front());
    std::stable_sort(detections.begin(), detections.end(),
                     [](const DetectionRecord& a, const DetectionRecord& b) { return a.frame < b.frame; });
    const MarkingScore twice = score_markings(visible, detections);
    CHECK(twice.matched == 3);
    CHECK(twice.detections == 6);
  }
}

namespace {

// A drive past known markings, what the ECU saw of them and the landmarks it
// made of them, in the order its logs list them.
class LandmarkScene {
 public:
  const Label forward = label_of("forward"), leftturn = label_of("leftturn"), stop = label_of("stop"),
              bike = label_of("bike"), rail = label_of("rail"), ped = label_of("ped");

  std::vector<Pose2> route;
  std::vector<double> times;
  std::vector<WorldMarking> world;
  std::vector<LandmarkRecord> landmarks;
  // The rows of each marking in frame order, as in visible.csv.
  std::vector<VisibleMarking> visible;
  MarkingScore paired;
  std::vector<DetectionRecord> detections;

  LandmarkScene() {
    // The car drives along x at 1 m a frame, 10 frames a second; from frame
    // 400 on it starts again at x = 0 (a second visit).
    for (std::size_t f = 0; f < 800; ++f) {
      route.push_back({f < 400 ? double(f) : double(f) - 400.0, 0.0, 0.0});
      times.push_back(double(f) / 10.0);
    }
    world = {
        {1, forward, 30.0, 0.0, 0.0},
        {2, stop, 60.0, 1.0, 0.0},
        {3, bike, 90.0, -2.0, 0.0},
        {4, rail, 120.0, 0.0, 0.0},
        {5, ped, 150.0, 8.0, 0.0},
        {6, stop, 200.0, 0.0, 0.0},
        {8, bike, 300.0, 0.0, 0.0},
        {9, stop, 15.0, 0.0, 0.0},
        {10, stop, 390.0, 0.0, 0.0},
        {11, forward, 350.0, 0.0, 0.0},
        {12, label_of("crosswalk"), 250.0, 0.0, 0.0},
    };
  }

  // A landmark at (x, y) on the truth's map, last seen at frame `last`, as the
  // ECU records it in its own odometry frame.
  void landmark(Label label, std::uint32_t observations, FrameIndex first, FrameIndex last, double x,
                double y) {
    LandmarkRecord l;
    l.label = label;
    l.observations = observations;
    l.first_frame = first;
    l.last_frame = last;
    const Pose2 car = compose(drift_, route[last]);
    const Pose2 at = compose(drift_, Pose2{x, y, 0.0});
    l.x = at.x;
    l.y = at.y;
    l.car_x = car.x;
    l.car_y = car.y;
    l.car_yaw = car.yaw;
    l.has_car_pose = true;
    landmarks.push_back(l);
  }

  // Marking `id` in view at `frame`, paired with a detection of `detected`.
  void show(std::uint32_t id, Label label, FrameIndex frame, std::optional<Label> detected) {
    visible.push_back({frame, id, label, {}});
    paired.paired_label.push_back(detected);
  }

  void detect(FrameIndex frame, Label label, double ahead, double left) {
    DetectionRecord d;
    d.frame = frame;
    d.label = label;
    d.ground_x = ahead;
    d.ground_y = left;
    detections.push_back(d);
  }

 private:
  // The ECU's odometry frame: turned and moved against the truth's.
  const Pose2 drift_{100.0, -40.0, 0.3};
};

// Each marking's rows, detections and landmarks, with the case each stands for.
LandmarkScene landmark_scene() {
  LandmarkScene s;
  // 1: 20..5 m ahead, a landmark of its class 0.3 m off. Seen again on the
  // second visit (its own pass, its own landmark).
  s.show(1, s.forward, 10, s.forward);
  s.show(1, s.forward, 25, s.forward);
  s.landmark(s.forward, 4, 10, 27, 30.3, 0.0);
  // 2: two landmarks on it; the one with more observations is another class.
  s.show(2, s.stop, 40, s.leftturn);
  s.show(2, s.stop, 46, s.leftturn);
  s.landmark(s.leftturn, 5, 40, 48, 60.0, 1.0);
  s.landmark(s.stop, 3, 41, 47, 60.2, 1.1);
  // 3: the first row lies 25 m ahead, out of range, but the pass counts by
  // its second. Not shown in the frames between, it is detected once where
  // it lies (a detection 5 m off is not its); no landmark.
  s.show(3, s.bike, 65, std::nullopt);
  s.show(3, s.bike, 80, s.bike);
  s.detect(70, s.bike, 19.5, -2.4);  // the car at x = 70: the marking 20 m ahead, 2 m right
  s.detect(72, s.ped, 13.0, 3.0);
  s.detect(80, s.bike, 10.0, -2.0);  // the detection paired with the visible row
  // 11: shown in one frame, detected again half a second later (the image
  // cuts it then); its landmark named right.
  s.detect(345, s.forward, 5.2, 0.3);
  s.paired.detection_paired = {false, false, true, false};
  s.show(11, s.forward, 340, s.forward);
  s.landmark(s.forward, 3, 340, 346, 350.0, 0.0);
  // 8: a landmark of its class, but from other frames than the pass's.
  s.show(8, s.bike, 290, s.bike);
  s.landmark(s.bike, 3, 100, 110, 300.0, 0.0);
  // 4: a landmark on it without the car's pose: not placed.
  s.show(4, s.rail, 110, s.rail);
  s.show(4, s.rail, 112, s.rail);
  s.landmark(s.rail, 3, 110, 114, 120.0, 0.0);
  s.landmarks.back().has_car_pose = false;
  // 5: 8 m to the side, never in range: not counted, though detected.
  s.show(5, s.ped, 140, s.ped);
  s.show(5, s.ped, 141, s.ped);
  // 6: in range, never detected; 4 s apart is still one pass.
  s.show(6, s.stop, 185, std::nullopt);
  s.show(6, s.stop, 225, std::nullopt);
  // 7: not in the world: not judged.
  s.show(7, s.stop, 190, s.stop);
  s.show(1, s.forward, 410, s.forward);
  s.show(1, s.forward, 420, s.forward);
  s.landmark(s.forward, 6, 410, 428, 30.0, 0.0);
  // 9: in view at the drive's first frame; 10: passed 24 m before its end.
  s.show(9, s.stop, 0, s.stop);
  s.show(9, s.stop, 1, s.stop);
  s.show(10, s.stop, 775, std::nullopt);
  // A landmark on no marking, and one on the crosswalk where it crosses the
  // next lane (3.5 m from its centre, across the road).
  s.landmark(s.ped, 3, 500, 510, 130.0, 4.0);
  s.landmark(label_of("crosswalk"), 5, 240, 248, 250.2, 3.5);
  return s;
}

}  // namespace

TEST_CASE("landmarks are placed by their offset from the car") {
  const LandmarkScene s = landmark_scene();
  const LandmarkScore placed = score_landmarks(s.world, s.route, s.landmarks);
  CHECK(placed.landmarks == 9);
  CHECK(placed.without_pose == 1);
  CHECK(placed.right_label == 6);
  CHECK(placed.wrong_label == 1);
  CHECK(placed.on_nothing == 1);
  REQUIRE(placed.marking_of[0].has_value());
  CHECK(s.world[*placed.marking_of[0]].id == 1);
  CHECK(placed.distance_m.max == Approx(0.3).margin(1e-6));
  CHECK_FALSE(placed.marking_of[7].has_value());
  // Listed for the reader: the leftturn on the stop line, and the ped on no
  // marking, 10.8 m from the nearest one (4, rail at x = 120).
  REQUIRE(placed.misplaced.size() == 2);
  CHECK(placed.misplaced[0].landmark == 1);
  CHECK(placed.misplaced[0].x == Approx(60.0).margin(1e-6));
  CHECK(placed.misplaced[0].y == Approx(1.0).margin(1e-6));
  REQUIRE(placed.misplaced[0].nearest.has_value());
  CHECK(s.world[*placed.misplaced[0].nearest].id == 2);
  CHECK(placed.misplaced[1].landmark == 7);
  REQUIRE(placed.misplaced[1].nearest.has_value());
  CHECK(s.world[*placed.misplaced[1].nearest].id == 4);
  CHECK(placed.misplaced[1].distance_m == Approx(std::hypot(10.0, 4.0)).margin(1e-6));
}

TEST_CASE("each pass of a marking is named by its landmark") {
  const LandmarkScene s = landmark_scene();
  const LandmarkScore placed = score_landmarks(s.world, s.route, s.landmarks);
  const PassScore score =
      score_passes(s.world, s.route, s.times, s.visible, s.detections, s.paired, s.landmarks, placed);
  REQUIRE(score.passes.size() == 8);
  CHECK(score.cut_by_drive_ends == 2);
  CHECK(score.count(PassOutcome::NamedRight) == 3);
  CHECK(score.count(PassOutcome::NamedWrong) == 1);
  CHECK(score.count(PassOutcome::NoLandmark) == 4);
  CHECK(score.passes_of_class[s.forward] == 3);
  CHECK(score.named_right_of_class[s.forward] == 3);
  CHECK(score.passes_of_class[s.ped] == 0);

  const MarkingPass& first = score.passes[0];
  CHECK(first.id == 1);
  CHECK(first.first_frame == 10);
  CHECK(first.last_frame == 25);
  CHECK(first.detections == 2);
  CHECK(first.outcome == PassOutcome::NamedRight);
  const MarkingPass& two_landmarks = score.passes[1];
  CHECK(two_landmarks.outcome == PassOutcome::NamedWrong);
  CHECK(two_landmarks.named == s.leftturn);
  const MarkingPass& not_shown = score.passes[2];
  CHECK(not_shown.id == 3);
  CHECK(not_shown.detections == 2);
  CHECK(not_shown.outcome == PassOutcome::NoLandmark);
  const MarkingPass& without_pose = score.passes[3];
  CHECK(without_pose.id == 4);
  CHECK(without_pose.outcome == PassOutcome::NoLandmark);
  const MarkingPass& unseen = score.passes[4];
  CHECK(unseen.outcome == PassOutcome::NoLandmark);
  CHECK(unseen.detections == 0);
  CHECK(unseen.first_frame == 185);
  CHECK(unseen.last_frame == 225);
  CHECK(score.passes[5].id == 8);
  CHECK(score.passes[5].outcome == PassOutcome::NoLandmark);
  const MarkingPass& cut_by_image = score.passes[6];
  CHECK(cut_by_image.id == 11);
  CHECK(cut_by_image.detections == 2);
  CHECK(cut_by_image.outcome == PassOutcome::NamedRight);
  CHECK(score.passes[7].first_frame == 410);
  CHECK(score.passes[7].outcome == PassOutcome::NamedRight);
}

TEST_CASE("malformed inputs are reported with file and line") {
  const fs::path dir = fresh_dir("malformed");
  std::string error;
  std::vector<VisibleMarking> visible;
  std::vector<DetectionRecord> detections;
  std::vector<WorldMarking> world;

  fixture::write_text(dir / "v.csv",
                      "frame,id,class,x1,y1,x2,y2,x3,y3,x4,y4\n1,0,stop,0,0,1,0,1,1,0,1\n"
                      "2,1,bogus,0,0,1,0,1,1,0,1\n");
  error = error_of(load_visible(dir / "v.csv", 10));
  CHECK(error == (dir / "v.csv").string() + ":3: class 'bogus' is not a marking class");

  fixture::write_text(dir / "v.csv", "frame,id,class,x1,y1,x2,y2,x3,y3,x4,y4\n10,0,stop,0,0,1,0,1,1,0,1\n");
  error = error_of(load_visible(dir / "v.csv", 10));
  CHECK(error == (dir / "v.csv").string() + ":2: frame 10 is beyond the truth's 10 frames (frames.csv)");

  fixture::write_text(dir / "v.csv", "frame,id,class,x1,y1,x2,y2,x3,y3,x4,y4\n1,0,stop,0,0,1,0,1,1,0\n");
  error = error_of(load_visible(dir / "v.csv", 10));
  CHECK_THAT(error, StartsWith((dir / "v.csv").string() + ":2: expected 11 comma-separated fields"));

  fixture::write_text(dir / "d.csv",
                      "frame,label,score,x1,y1,x2,y2,x3,y3,x4,y4,ground_x,ground_y\n"
                      "1,stop,0.5,0,0,1,0,1,1,0,1,2,3\n1,stop,1.5,0,0,1,0,1,1,0,1,2,3\n");
  error = error_of(load_detections(dir / "d.csv", 10));
  CHECK(error == (dir / "d.csv").string() + ":3: score 1.5 is outside [0, 1]");

  fixture::write_text(dir / "d.csv",
                      "frame,label,score,x1,y1,x2,y2,x3,y3,x4,y4,ground_x,ground_y\n"
                      "1.5,stop,0.5,0,0,1,0,1,1,0,1,2,3\n");
  error = error_of(load_detections(dir / "d.csv", 10));
  CHECK_THAT(error, StartsWith((dir / "d.csv").string() + ":2: frame is not a whole number"));

  fixture::write_text(dir / "d.csv",
                      "frame,label,score,x1,y1,x2,y2,x3,y3,x4,y4,ground_x,ground_y\n"
                      "1,stop,0.5,0,0,1,0,1,1,0,nan,2,3\n");
  error = error_of(load_detections(dir / "d.csv", 10));
  CHECK(error == (dir / "d.csv").string() + ":2: y4 is not a finite number: 'nan'");

  fixture::write_text(dir / "d.csv",
                      "frame,label,score,x1,y1,x2,y2,x3,y3,x4,y4,ground_x,ground_y,turned\n"
                      "1,bike,0.5,0,0,1,0,1,1,0,1,2,3,1\n2,bike,0.5,0,0,1,0,1,1,0,1,2,3,0\n");
  const Result<std::vector<DetectionRecord>> turned = load_detections(dir / "d.csv", 10);
  REQUIRE(turned);
  REQUIRE(turned->size() == 2);
  CHECK((*turned)[0].turned);
  CHECK_FALSE((*turned)[1].turned);

  fixture::write_text(dir / "d.csv",
                      "frame,label,score,x1,y1,x2,y2,x3,y3,x4,y4,ground_x,ground_y,turned\n"
                      "1,bike,0.5,0,0,1,0,1,1,0,1,2,3,2\n1,bike,0.5,0,0,1,0,1,1,0,1,2,3\n");
  error = error_of(load_detections(dir / "d.csv", 10));
  CHECK_THAT(error, StartsWith((dir / "d.csv").string() + ":2: turned"));

  fixture::write_text(dir / "d.csv",
                      "frame,label,score,x1,y1,x2,y2,x3,y3,x4,y4,ground_x,ground_y,turned\n"
                      "1,bike,0.5,0,0,1,0,1,1,0,1,2,3\n");
  error = error_of(load_detections(dir / "d.csv", 10));
  CHECK_THAT(error, StartsWith((dir / "d.csv").string() + ":2: expected 14 comma-separated fields"));

  fixture::write_text(
      dir / "l.csv",
      "label,observations,first_frame,last_frame,x,y,car_x,car_y,car_yaw,has_car_pose,facing\n"
      "bike,4,1,3,10,0,9,0,0,1,2\n");
  const Result<std::vector<LandmarkRecord>> facing = load_landmarks(dir / "l.csv", 10);
  REQUIRE(facing);
  REQUIRE(facing->size() == 1);
  CHECK((*facing)[0].facing == Facing::kAgainst);
  fixture::write_text(
      dir / "l.csv",
      "label,observations,first_frame,last_frame,x,y,car_x,car_y,car_yaw,has_car_pose,facing\n"
      "bike,4,1,3,10,0,9,0,0,1,3\n");
  error = error_of(load_landmarks(dir / "l.csv", 10));
  CHECK_THAT(error, StartsWith((dir / "l.csv").string() + ":2: facing is not a whole number below 3"));

  fixture::write_text(dir / "m.csv", "id,class,x,y\n");
  error = error_of(load_world_markings(dir / "m.csv"));
  CHECK(error == (dir / "m.csv").string() + ":1: expected the header 'id,class,x,y,heading'");

  error = error_of(load_world_markings(dir / "absent.csv"));
  CHECK(error == (dir / "absent.csv").string() + ": cannot open: No such file or directory");
  error = error_of(load_world_markings(dir));
  CHECK(error == dir.string() + ": is a directory, not a CSV file");

  fixture::write_text(dir / "c.log",
                      "(0000000001.000000) vcan0 2A0#0011223344556677\n"
                      "(0000000001.000100) vcan0 2A0#00112233445566ZZ\n");
  EcuCanLog log;
  error = read_error(dir / "c.log");
  CHECK_FALSE(error.empty());
  CHECK_THAT(error, StartsWith((dir / "c.log").string() + ":2:"));
}

TEST_CASE("a CAN log off the drive's clock, cut short or not the ECU's is told") {
  const fs::path dir = fresh_dir("can-clock");
  const std::string path = (dir / "c.log").string();
  EcuCanLog log;
  std::string error;
  const DriveTimes drive{0.0, 79.9};

  // Stamps on the wall clock: refused at the first line, with the drive's span.
  fixture::write_text(path, "(1733130000.100000) vcan0 2B0#0011223344556677\n");
  error = read_error(path, &drive);
  CHECK_FALSE(error.empty());
  CHECK_THAT(error,
             StartsWith(path + ":1: stamp 1733130000.100000 s lies outside the drive (0.000 to 79.900 s"));
  // ... but read without a drive to hold them against.
  log = read_log(path);
  // Within the allowance either side of the drive.
  fixture::write_text(path,
                      "(0000000000.000000) vcan0 2B0#0011223344556677\n"
                      "(0000000139.900000) vcan0 2B0#0011223344556677\n");
  log = read_log(path, &drive);
  fixture::write_text(path,
                      "(0000000000.000000) vcan0 2B0#0011223344556677\n"
                      "(0000000140.000000) vcan0 2B0#0011223344556677\n");
  error = read_error(path, &drive);
  CHECK_FALSE(error.empty());
  CHECK_THAT(error, StartsWith(path + ":2: stamp 140.000000 s lies outside the drive"));

  // Going back in time.
  fixture::write_text(path,
                      "(0000000002.000000) vcan0 2B0#0011223344556677\n"
                      "(0000000002.000000) vcan0 2B0#0011223344556677\n"
                      "(0000000001.999999) vcan0 2B0#0011223344556677\n");
  error = read_error(path, &drive);
  CHECK_FALSE(error.empty());
  CHECK_THAT(error, StartsWith(path + ":3: stamp 1.999999 s is before the line above's 2.000000 s"));

  // A last line cut short (no newline, too few bytes on an ECU id) is an
  // error; the same frame on a whole line is a frame of the wrong length.
  fixture::write_text(path,
                      "(0000000001.000000) vcan0 120#0011223344556677\n"
                      "(0000000001.000000) vcan0 2A0#0011223344");
  error = read_error(path, &drive);
  CHECK_FALSE(error.empty());
  CHECK(error == path +
                     ":2: the last line is cut short: no newline at its end, and its frame has 5 bytes "
                     "where the ECU sends 8 (was the log cut?)");
  fixture::write_text(path,
                      "(0000000001.000000) vcan0 120#0011223344556677\n"
                      "(0000000001.000000) vcan0 2A0#0011223344\n");
  log = read_log(path, &drive);
  CHECK(log.loop_frames.wrong_length == 1);
  CHECK(can_log_warnings(path, log) ==
        std::vector<std::string>{path +
                                 ":2: 1 of 1 LoopDetection and Status frames have the wrong length (this one "
                                 "5 bytes, the DBC's 8): rejected, counted under 'length'"});
  // Another id's frame without a newline is no ECU frame to judge.
  fixture::write_text(path, "(0000000001.000000) vcan0 120#0011");
  log = read_log(path, &drive);
  CHECK(can_log_warnings(path, log) ==
        std::vector<std::string>{path +
                                 ": no LoopDetection or Status frame: is this the ECU's log? (its one frame "
                                 "is of another id)"});

  // The fixture's own log: nothing to say.
  log = read_log(dir / "ecu-can.log", &drive);
  CHECK(can_log_warnings(dir / "ecu-can.log", log).empty());
}

TEST_CASE("the picture is written as SVG and PNG") {
  const fs::path dir = fresh_dir("figure");
  std::vector<Pose2> route;
  std::vector<double> times;
  std::vector<WorldMarking> world;
  std::string error;
  {
    auto truth = loaded(replay::load_truth(dir / "frames.csv"));
    route = std::move(truth.poses);
    times = std::move(truth.times);
  }
  world = loaded(load_world_markings(dir / "markings.csv"));
  EcuCanLog log;
  log = read_log(dir / "ecu-can.log");
  const replay::TruthJudge judge(route, 5.0, 100.0);
  const LoopScore score = score_loops(judge, times, log.loops);
  FigureContent content{&route, &world, &score.outcomes, "title & <figures>", "subtitle"};
  REQUIRE(write_svg(dir / "loops.svg", content));
  REQUIRE(write_png(dir / "loops.png", content));
  CHECK(fs::file_size(dir / "loops.png") > 1000);
  std::string svg;
  {
    std::FILE* f = std::fopen((dir / "loops.svg").c_str(), "r");
    REQUIRE(f != nullptr);
    char buffer[4096];
    std::size_t n = 0;
    while ((n = std::fread(buffer, 1, sizeof buffer, f)) > 0) svg.append(buffer, n);
    std::fclose(f);
  }
  CHECK(svg.find("title &amp; &lt;figures&gt;") != std::string::npos);
  CHECK(svg.find("frame 553 - frame 150") != std::string::npos);
  CHECK(svg.find("stroke=\"#dc1e1e\"") != std::string::npos);  // the wrong loop, red
  CHECK(svg.find(">crosswalk<") != std::string::npos);         // legend
  CHECK(svg.ends_with("</svg>\n"));

  const Status unwritten = write_png((dir / "no-such-dir" / "x.png").string(), content);
  REQUIRE_FALSE(unwritten);
  CHECK_THAT(unwritten.message(), StartsWith((dir / "no-such-dir" / "x.png").string()));
}
