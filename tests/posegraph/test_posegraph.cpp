// markloop-posegraph: a drifting circle driven twice, corrected by its loops;
// a wrong loop that must not bend it; bad inputs; the command line.
#include <catch2/catch_approx.hpp>
#include <catch2/catch_test_macros.hpp>
#include <catch2/matchers/catch_matchers_string.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

#include "app/common/units.hpp"
#include "app/tools/posegraph/graph.hpp"
#include "app/tools/posegraph/inputs.hpp"
#include "app/tools/posegraph/metrics.hpp"
#include "app/tools/posegraph/solver.hpp"
#include "tests/eval/eval_fixture.hpp"

namespace {

using namespace markloop;
using namespace markloop::posegraph;
using Catch::Matchers::ContainsSubstring;

constexpr double kRadius_m = 80.0, kSpeed = 10.0, kFpsHz = 10.0;
constexpr double kLapFrames = 2 * std::numbers::pi * kRadius_m / kSpeed * kFpsHz;  // about 503
constexpr std::size_t kDriveFrames = 1000;                                         // two laps
constexpr double kYawBias_dps = 0.3;

Pose2 truth_at(double t) {
  const double a = kSpeed * t / kRadius_m;
  return {kRadius_m * std::sin(a), kRadius_m * (1.0 - std::cos(a)), a};
}

Truth circle_truth() {
  Truth truth;
  for (std::size_t k = 0; k < kDriveFrames; ++k)
    truth.poses.push_back(truth_at(static_cast<double>(k) / kFpsHz));
  truth.known.assign(truth.poses.size(), true);
  return truth;
}

// VehicleOdometry every 20 ms with a yaw-rate bias (and the wheel speed
// `speed_scale` times the truth): the dead reckoning drifts.
void write_odometry(const std::filesystem::path& path, double speed_scale = 1.0) {
  eval::fixture::CandumpFile log(path);
  dbc::E2eSenderState sender;
  for (int i = 0; i * 0.02 <= static_cast<double>(kDriveFrames) / kFpsHz + 0.05; ++i) {
    dbc::VehicleOdometry m;
    m.wheel_speed_m_per_s = kSpeed * speed_scale;
    m.yaw_rate_deg_per_s = kSpeed / kRadius_m * kDegreesPerRadian + kYawBias_dps;
    m.wheel_speed_valid = true;
    m.yaw_rate_valid = true;
    log.write(dbc::encode_frame(m, sender), i * 0.02);
  }
}

// In the second lap, every 20 m: the same place one lap back, its true
// relative pose.
std::vector<LoopMeasurement> true_loops(const Truth& truth) {
  std::vector<LoopMeasurement> loops;
  for (std::size_t query = 520; query < kDriveFrames; query += 20) {
    const auto match = static_cast<FrameIndex>(std::lround(static_cast<double>(query) - kLapFrames));
    loops.push_back({static_cast<FrameIndex>(query), match,
                     compose(inverse(truth.poses[match]), truth.poses[query]), 0.05});
  }
  return loops;
}

struct Corrected {
  double before_m, after_m;
  SolveReport report;
};

Corrected correct(const std::vector<Pose2>& odometry, const std::vector<LoopMeasurement>& loops,
                  const Truth& truth, const SolverOptions& solver = {}) {
  GraphOptions options;
  options.odometry.yaw_rate_error_dps = 0.3;
  const PoseGraph graph = build_graph(odometry, loops, options);
  Result<SolveReport> solved = optimise(graph, solver);
  REQUIRE(solved);
  const std::vector<Pose2> after = frames_from_nodes(graph, solved->nodes, odometry, solved->scale);
  return {trajectory_error(odometry, truth)->ate_rmse_m, trajectory_error(after, truth)->ate_rmse_m, *solved};
}

std::filesystem::path scratch(const char* name) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

std::vector<Pose2> odometry_of_circle(const std::filesystem::path& dir, double speed_scale = 1.0) {
  write_odometry(dir / "odometry.log", speed_scale);
  Result<OdometryTrack> track = read_odometry_log((dir / "odometry.log").string(), kFpsHz);
  REQUIRE(track);
  REQUIRE(track->poses.size() >= kDriveFrames);
  REQUIRE(track->frames_without_pose == 0);
  return std::vector<Pose2>(track->poses.begin(), track->poses.begin() + kDriveFrames);
}

}  // namespace

TEST_CASE("the loops correct a drifting circle") {
  const Truth truth = circle_truth();
  const std::vector<Pose2> odometry = odometry_of_circle(scratch("posegraph-circle"));
  const Corrected c = correct(odometry, true_loops(truth), truth);
  CHECK(c.before_m > 5.0);
  CHECK(c.after_m < 0.1 * c.before_m);
  CHECK(c.after_m < 0.5);
  CHECK(c.report.loops_rejected == 0);
}

TEST_CASE("a wrong loop does not bend the map") {
  const Truth truth = circle_truth();
  const std::vector<Pose2> odometry = odometry_of_circle(scratch("posegraph-wrong"));
  std::vector<LoopMeasurement> loops = true_loops(truth);
  const double clean_m = correct(odometry, loops, truth).after_m;
  // Half a lap apart (160 m across the circle), said to be the same place.
  loops.push_back({900, static_cast<FrameIndex>(900 - kLapFrames / 2), Pose2{0.5, 0.0, 0.0}, 0.05});
  const Corrected robust = correct(odometry, loops, truth);
  CHECK(robust.after_m < 1.5 * clean_m + 0.05);
  CHECK(robust.report.loop_rejected.back());
  SolverOptions plain;
  plain.robust_scales = {};
  CHECK(correct(odometry, loops, truth, plain).after_m > 5.0 * clean_m);
}

TEST_CASE("the scale estimate is not pulled by wrong loops when the odometry has no scale error") {
  const Truth truth = circle_truth();
  const std::vector<Pose2> odometry = odometry_of_circle(scratch("posegraph-scale"));
  std::vector<LoopMeasurement> loops = corrupt_loops(true_loops(truth), 0.2, 1, truth.poses, 100.0);
  SolverOptions solver;
  solver.estimate_scale = true;
  const Corrected c = correct(odometry, loops, truth, solver);
  CHECK(std::abs(c.report.scale) < 0.002);
  CHECK(c.after_m < 0.1 * c.before_m);
}

TEST_CASE("the camera's measure of the scale corrects what the loops cannot") {
  // The wheel speed reads 2 % high: every lap closes, only bigger.
  const Truth truth = circle_truth();
  const std::vector<Pose2> odometry = odometry_of_circle(scratch("posegraph-camera-scale"), 1.02);
  const Corrected loops_only = correct(odometry, true_loops(truth), truth);
  SolverOptions solver;
  solver.scale_prior_mean = 1.0 / 1.02 - 1.0;
  solver.scale_prior_sigma = 0.002;
  const Corrected with_camera = correct(odometry, true_loops(truth), truth, solver);
  CHECK(with_camera.report.scale == Catch::Approx(1.0 / 1.02 - 1.0).margin(0.002));
  CHECK(with_camera.after_m < 0.5 * loops_only.after_m);
  CHECK(with_camera.after_m < 0.1 * with_camera.before_m);
}

TEST_CASE("the ECU's OdometryScale is read from its Status pages, only when valid") {
  const auto dir = scratch("posegraph-status");
  const auto write_status = [&](const char* name, bool valid, bool odometry_page) {
    eval::fixture::CandumpFile log(dir / name);
    dbc::E2eSenderState sender;
    dbc::Status status;
    status.odometry_scale_valid = valid;
    status.odometry_scale = 1.0123;
    status.odometry_scale_error = 0.0004;
    for (const dbc::StatusPage page : dbc::Status::kPages) {
      if (page == dbc::StatusPage::Odometry && !odometry_page) continue;
      status.status_page = page;
      log.write(dbc::encode_frame(status, sender), 1.0);
    }
  };
  write_status("valid.log", true, true);
  write_status("invalid.log", false, true);
  write_status("older-ecu.log", true, false);
  const Result<LoopInput> valid = read_ecu_loops((dir / "valid.log").string(), kDriveFrames);
  REQUIRE(valid);
  REQUIRE(valid->camera_scale.has_value());
  CHECK(valid->camera_scale->scale == Catch::Approx(1.0123));
  CHECK(valid->camera_scale->standard_error == Catch::Approx(0.0004));
  for (const char* name : {"invalid.log", "older-ecu.log"}) {
    const Result<LoopInput> none = read_ecu_loops((dir / name).string(), kDriveFrames);
    REQUIRE(none);
    CHECK_FALSE(none->camera_scale.has_value());
  }
}

TEST_CASE("loop frames attached by the odometry correct as well as loop frames with nodes") {
  const Truth truth = circle_truth();
  const std::vector<Pose2> odometry = odometry_of_circle(scratch("posegraph-attached"));
  GraphOptions options;
  options.odometry.yaw_rate_error_dps = 0.3;
  const std::vector<LoopMeasurement> loops = true_loops(truth);
  double after_m[2];
  for (const bool loop_nodes : {false, true}) {
    options.loop_nodes = loop_nodes;
    const PoseGraph graph = build_graph(odometry, loops, options);
    const Result<SolveReport> solved = optimise(graph);
    REQUIRE(solved);
    after_m[loop_nodes ? 1 : 0] =
        trajectory_error(frames_from_nodes(graph, solved->nodes, odometry), truth)->ate_rmse_m;
    // The frames between nodes are placed without a jump.
    const std::vector<Pose2> frames = frames_from_nodes(graph, solved->nodes, odometry);
    for (std::size_t k = 1; k < frames.size(); ++k)
      CHECK(std::hypot(frames[k].x - frames[k - 1].x, frames[k].y - frames[k - 1].y) < 1.5);
  }
  CHECK(after_m[0] < 1.2 * after_m[1] + 0.02);
}

TEST_CASE("bad input: a log cut mid-line is an error naming its line") {
  const auto dir = scratch("posegraph-cut");
  write_odometry(dir / "odometry.log");
  std::ifstream in(dir / "odometry.log");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  text.resize(text.size() - 5);
  std::ofstream(dir / "cut.log") << text;
  const Result<OdometryTrack> track = read_odometry_log((dir / "cut.log").string(), kFpsHz);
  REQUIRE_FALSE(track);
  CHECK_THAT(track.message(), ContainsSubstring("cut.log:"));
}

TEST_CASE("bad input: a loop outside the recording is an error, missing pages a counted skip") {
  const auto dir = scratch("posegraph-loops");
  {
    eval::fixture::CandumpFile log(dir / "ecu.log");
    dbc::E2eSenderState sender;
    eval::fixture::send_detection(log, sender, 1, 600, 97, 0.1, 0.0, 0.0, 60.0);
    eval::fixture::send_detection(log, sender, 2, 700, 197, 0.1, 0.0, 0.0, 70.0, 3);  // page 3 broken
    eval::fixture::send_detection(log, sender, 3, 5000, 197, 0.1, 0.0, 0.0, 80.0);
  }
  const Result<LoopInput> outside = read_ecu_loops((dir / "ecu.log").string(), kDriveFrames);
  REQUIRE_FALSE(outside);
  CHECK_THAT(outside.message(), ContainsSubstring("ecu.log:18: loop 5000 -> 197 names a frame outside"));
  const Result<LoopInput> inside = read_ecu_loops((dir / "ecu.log").string(), 6000);
  REQUIRE(inside);
  CHECK(inside->loops.size() == 2);
  CHECK(inside->incomplete == 1);
}

TEST_CASE("command line: writes the trajectories and prints the ATE") {
  const auto dir = scratch("posegraph-cli");
  write_odometry(dir / "odometry.log");
  {
    eval::fixture::CandumpFile log(dir / "ecu.log");
    dbc::E2eSenderState sender;
    const Truth truth = circle_truth();
    double t = 60.0;
    for (const LoopMeasurement& m : true_loops(truth)) {
      t += 0.1;
      eval::fixture::send_detection(log, sender, static_cast<std::uint8_t>(t), m.query, m.match, m.relative.x,
                                    m.relative.y, m.relative.yaw * kDegreesPerRadian, t);
    }
    // An OdometryScale no wheel could give: reported, not used.
    dbc::E2eSenderState status_sender;
    dbc::Status status;
    status.status_page = dbc::StatusPage::Odometry;
    status.odometry_scale_valid = true;
    status.odometry_scale = 0.9;
    log.write(dbc::encode_frame(status, status_sender), t + 1.0);
    std::ofstream frames(dir / "frames.csv");
    frames << "frame,t,x,y,yaw\n";
    for (std::size_t k = 0; k < truth.poses.size(); ++k)
      frames << k << ',' << static_cast<double>(k) / kFpsHz << ',' << truth.poses[k].x << ','
             << truth.poses[k].y << ',' << truth.poses[k].yaw << '\n';
  }
  const std::string run = std::string(MARKLOOP_POSEGRAPH_BIN) + " --can-in " +
                          (dir / "odometry.log").string() + " --can-out " + (dir / "ecu.log").string() +
                          " --truth " + (dir / "frames.csv").string() + " --yaw-rate-error 0.3 --out " +
                          (dir / "out").string();
  REQUIRE(std::system((run + " > " + (dir / "stdout.txt").string()).c_str()) == 0);
  std::ifstream out(dir / "stdout.txt");
  const std::string printed((std::istreambuf_iterator<char>(out)), std::istreambuf_iterator<char>());
  CHECK_THAT(printed, ContainsSubstring("ATE (RMSE after SE(2) alignment"));
  CHECK_THAT(printed,
             ContainsSubstring("odometry scale by the camera: 0.90000 +- 0.00000 (not used: beyond"));
  for (const char* file : {"before.tum", "after.tum", "before.kitti", "after.kitti", "posegraph.svg"})
    CHECK(std::filesystem::file_size(dir / "out" / file) > 0);
  std::ifstream tum(dir / "out" / "after.tum");
  double t, x, y, z, qx, qy, qz, qw;
  tum >> t >> x >> y >> z >> qx >> qy >> qz >> qw;
  CHECK(t == 0.0);
  // An output over an input is refused with status 2, before anything runs.
  const std::string overwrite =
      std::string(MARKLOOP_POSEGRAPH_BIN) + " --can-in " + (dir / "out/before.tum").string() + " --can-out " +
      (dir / "ecu.log").string() + " --out " + (dir / "out").string() + " 2> /dev/null";
  CHECK(WEXITSTATUS(std::system(overwrite.c_str())) == 2);
  // The scale given by hand: within the bound only, and not with its opposite.
  CHECK(WEXITSTATUS(std::system((run + " --camera-scale 1.5 2> /dev/null").c_str())) == 2);
  CHECK(WEXITSTATUS(std::system((run + " --camera-scale 1.01 --no-camera-scale 2> /dev/null").c_str())) == 2);
  REQUIRE(std::system((run + " --camera-scale 1.01 > " + (dir / "given.txt").string()).c_str()) == 0);
  std::ifstream given(dir / "given.txt");
  const std::string given_printed((std::istreambuf_iterator<char>(given)), std::istreambuf_iterator<char>());
  CHECK_THAT(given_printed,
             ContainsSubstring("odometry scale by the camera: 1.01000 +- 0.00000; prior on s -0.0099"));
}
