#include <catch2/catch_test_macros.hpp>
#include <catch2/matchers/catch_matchers_floating_point.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "app/io/y4m.hpp"
#include "dbc/markloop_messages.hpp"
#include "drivers/can/candump_log.hpp"
#include "sim/recorder.hpp"
#include "sim/render.hpp"

using namespace markloop;
using namespace markloop::sim;
using Catch::Matchers::WithinAbs;

namespace {

std::filesystem::path scratch(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / "markloop-sim-tests" / name;
  std::filesystem::remove_all(dir);
  return dir;
}

std::vector<std::string> lines_of(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::string bytes_of(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> fields;
  std::stringstream s(line);
  for (std::string f; std::getline(s, f, ',');) fields.push_back(f);
  return fields;
}

RecordOptions short_drive(const std::filesystem::path& dir, std::uint64_t seed) {
  RecordOptions o;
  o.out_dir = dir.string();
  o.seed = seed;
  o.conditions.seed = seed * 31 + 7;
  o.max_frames = 30;
  o.progress = false;
  return o;
}

const perception::CameraModel& camera() {
  static const perception::CameraModel model = perception::default_camera_model();
  return model;
}

// visible.csv: markings of the world, quads inside the image.
void check_visible_csv(const std::filesystem::path& dir, const std::map<std::string, std::string>& class_of) {
  const auto visible = lines_of(dir / "visible.csv");
  CHECK(visible[0] == "frame,id,class,x1,y1,x2,y2,x3,y3,x4,y4");
  REQUIRE(visible.size() > 10);
  for (std::size_t i = 1; i < visible.size(); ++i) {
    const auto f = split(visible[i]);
    REQUIRE(f.size() == 11);
    CHECK(std::stoi(f[0]) < 30);
    CHECK(class_of.at(f[1]) == f[2]);
    for (int k = 3; k < 11; k += 2) {
      CHECK(std::stod(f[k]) >= 0.0);
      CHECK(std::stod(f[k]) <= 1279.0);
      CHECK(std::stod(f[k + 1]) >= 0.0);
      CHECK(std::stod(f[k + 1]) <= 511.0);
    }
    // Near corners lie lower in the image than far ones.
    CHECK(std::stod(f[4]) > std::stod(f[8]));
  }
}

// odometry.log: VehicleOdometry every 20 ms from t = 0, valid E2E; `truth`
// is frames.csv.
void check_odometry_log(const std::filesystem::path& dir, const std::vector<std::string>& truth) {
  const auto log = lines_of(dir / "odometry.log");
  REQUIRE(log.size() == 146);  // 0 .. 2.9 s
  CHECK(log[0].rfind("(0000000000.000000) vcan0 120#", 0) == 0);
  dbc::E2eReceiverState e2e;
  double heading_change = 0.0;
  for (std::size_t i = 0; i < log.size(); ++i) {
    can::CandumpRecord record;
    can::CandumpLineError line_error;
    REQUIRE(can::parse_candump_line(log[i], record, line_error));
    CHECK(record.frame.id == dbc::VehicleOdometry::kId);
    CHECK(record.frame.timestamp_ns == static_cast<std::int64_t>(i) * 20'000'000);
    dbc::VehicleOdometry odo;
    REQUIRE(dbc::decode(record.frame.payload(), e2e, odo) == dbc::DecodeError::None);
    CHECK(odo.wheel_speed_valid);
    CHECK_THAT(odo.wheel_speed_m_per_s, WithinAbs(10.0, 0.2));
    heading_change += odo.yaw_rate_deg_per_s * 0.02;
  }
  // The yaw rates add up to the truth's heading change (plus bias, noise).
  const auto first = split(truth[1]), last = split(truth[30]);
  const double truth_change =
      std::remainder(std::stod(last[4]) - std::stod(first[4]), 2 * 3.141592653589793) * 180 /
      3.141592653589793;
  CHECK_THAT(heading_change, WithinAbs(truth_change, 1.0));

  // A corrupted payload fails the CRC.
  can::CandumpRecord record;
  can::CandumpLineError line_error;
  REQUIRE(can::parse_candump_line(log[5], record, line_error));
  record.frame.data[3] ^= 0x10;
  dbc::VehicleOdometry odo;
  CHECK(dbc::decode(record.frame.payload(), odo) == dbc::DecodeError::BadCrc);
}

}  // namespace

TEST_CASE("a drive's files have the agreed formats") {
  const auto dir = scratch("formats");
  const auto scenario = make_scenario("grid", 4);
  REQUIRE(scenario);
  const auto recorded = record_drive(*scenario, camera(), short_drive(dir, 4));
  REQUIRE(recorded);
  const RecordSummary& summary = *recorded;
  std::string error;
  CHECK(summary.frames == 30);

  // frames.y4m: mono, camera size, 10 fps, 30 frames.
  io::Y4mReader video;
  REQUIRE(video.open((dir / "frames.y4m").string()));
  CHECK(video.format().width == 1280);
  CHECK(video.format().height == 512);
  CHECK(video.format().chroma == io::Y4mChroma::kMono);
  CHECK_THAT(video.format().frame_period_s(), WithinAbs(0.1, 1e-9));
  std::vector<std::uint8_t> luma(video.format().luma_bytes());
  int frames = 0;
  while (video.read_frame(luma) == io::Y4mRead::kFrame) ++frames;
  CHECK(frames == 30);

  // frames.csv: header and one row per frame, 0.1 s apart.
  const auto truth = lines_of(dir / "frames.csv");
  REQUIRE(truth.size() == 31);
  CHECK(truth[0] == "frame,t,x,y,yaw");
  CHECK(split(truth[30])[0] == "29");
  CHECK(split(truth[30])[1] == "2.900");

  // markings.csv: every marking of the world.
  const auto markings = lines_of(dir / "markings.csv");
  CHECK(markings[0] == "id,class,x,y,heading");
  REQUIRE(markings.size() == scenario->markings.size() + 1);
  std::map<std::string, std::string> class_of;
  for (std::size_t i = 1; i < markings.size(); ++i) {
    const auto f = split(markings[i]);
    REQUIRE(f.size() == 5);
    class_of[f[0]] = f[1];
  }

  check_visible_csv(dir, class_of);
  check_odometry_log(dir, truth);

  // camera.yaml: the calibration used.
  const auto loaded = perception::load_camera_model((dir / "camera.yaml").string());
  REQUIRE(loaded);
  CHECK(loaded->width() == 1280);
  CHECK_THAT(loaded->mounting().height_m, WithinAbs(1.5, 1e-9));

  // Legacy replay files.
  CHECK(lines_of(dir / "poses.txt").size() == 30);
  CHECK(std::filesystem::exists(dir / "markings.txt"));
}

TEST_CASE("a drive is byte-identical for a seed and differs for another") {
  const auto scenario = make_scenario("loop", 9);
  const auto other = make_scenario("loop", 10);
  REQUIRE(record_drive(*scenario, camera(), short_drive(scratch("seed-a"), 9)));
  REQUIRE(record_drive(*scenario, camera(), short_drive(scratch("seed-b"), 9)));
  REQUIRE(record_drive(*other, camera(), short_drive(scratch("seed-c"), 10)));
  const auto root = std::filesystem::temp_directory_path() / "markloop-sim-tests";
  for (const char* file : {"frames.y4m", "odometry.log", "frames.csv", "markings.csv", "visible.csv",
                           "markings.txt", "poses.txt"}) {
    INFO(file);
    CHECK(bytes_of(root / "seed-a" / file) == bytes_of(root / "seed-b" / file));
  }
  for (const char* file : {"frames.y4m", "odometry.log", "markings.csv"}) {
    INFO(file);
    CHECK(bytes_of(root / "seed-a" / file) != bytes_of(root / "seed-c" / file));
  }
}

TEST_CASE("a place looks the same and shows the same markings on every pass") {
  const auto scenario = make_scenario("loop", 2);
  Renderer renderer(camera(), *scenario);
  Conditions c;
  c.noise_sigma = 0.0;  // sensor noise differs per frame by design
  c.occluder_probability = 0.0;
  const double lap = scenario->road.length();
  int compared = 0;
  for (double s = 50.0; s < lap; s += 97.0) {
    const Pose2 pose = scenario->road.at(s);
    cv::Mat first, second;
    renderer.render(pose, 10.0, c, 1, {}, first);
    // The second lap's pose is computed from a lap later (same point).
    const Pose2 again = scenario->road.at(std::fmod(s + lap, lap));
    renderer.render(again, 10.0, c, 2000, {}, second);
    CHECK(cv::norm(first, second, cv::NORM_INF) == 0.0);
    std::vector<VisibleMarking> a, b;
    renderer.visible_markings(pose, 3.0, 25.0, {}, a);
    renderer.visible_markings(again, 3.0, 25.0, {}, b);
    REQUIRE(a.size() == b.size());
    for (std::size_t i = 0; i < a.size(); ++i) {
      CHECK(a[i].id == b[i].id);
      CHECK(a[i].quad == b[i].quad);
    }
    compared += static_cast<int>(a.size());
  }
  CHECK(compared > 5);
}

TEST_CASE("rendered markings are where visible.csv says") {
  // Without wear or noise, a marking's quad encloses bright paint on a dark
  // road; the rest of the road stays dark.
  const auto scenario = make_scenario("ring", 3);
  Renderer renderer(camera(), *scenario);
  Conditions c;
  c.noise_sigma = 0.0;
  c.paint_wear = 0.0;
  c.shadows = false;
  c.occluder_probability = 0.0;
  int checked = 0;
  for (double s = 30.0; s < 1500.0 && checked < 10; s += 13.0) {
    const Pose2 pose = scenario->road.at(s);
    std::vector<VisibleMarking> seen;
    renderer.visible_markings(pose, 5.0, 15.0, {}, seen);
    if (seen.empty()) continue;
    cv::Mat image;
    renderer.render(pose, 10.0, c, 0, {}, image);
    for (const VisibleMarking& v : seen) {
      std::vector<cv::Point> quad;
      for (const auto& p : v.quad) quad.emplace_back(static_cast<int>(p[0]), static_cast<int>(p[1]));
      cv::Mat mask = cv::Mat::zeros(image.size(), CV_8U);
      cv::fillConvexPoly(mask, quad, cv::Scalar(255));
      double brightest = 0;
      cv::minMaxLoc(image, nullptr, &brightest, nullptr, nullptr, mask);
      CHECK(brightest > 150);  // paint
      ++checked;
    }
  }
  CHECK(checked >= 5);
}

TEST_CASE("the training set has the real dataset's annotation format") {
  const auto dir = scratch("training");
  TrainingSetOptions o;
  o.out_dir = dir.string();
  o.frames = 4;
  o.progress = false;
  const auto recorded = record_training_set(camera(), o);
  REQUIRE(recorded);
  const std::size_t annotations = *recorded;
  CHECK(annotations >= 4);
  const auto rows = lines_of(dir / "annotations.csv");
  CHECK(rows[0] == "image,label,x1,y1,x2,y2,x3,y3,x4,y4");
  REQUIRE(rows.size() == annotations + 1);
  for (std::size_t i = 1; i < rows.size(); ++i) {
    const auto f = split(rows[i]);
    REQUIRE(f.size() == 10);
    CHECK(perception::marking_class_from_name(f[1]).has_value());
    const cv::Mat image = cv::imread((dir / "images" / f[0]).string(), cv::IMREAD_UNCHANGED);
    REQUIRE(!image.empty());
    CHECK(image.type() == CV_8UC1);
    CHECK(image.cols == 1280);
  }
  CHECK(std::filesystem::exists(dir / "images" / "000003.png"));
  CHECK(std::filesystem::exists(dir / "camera.yaml"));
}

TEST_CASE("markings behind a vehicle ahead are not listed as visible") {
  const auto scenario = make_scenario("grid", 2);
  Renderer renderer(camera(), *scenario);
  std::vector<VisibleMarking> clear, hidden;
  int compared = 0;
  for (double s = 20.0; s < 2000.0; s += 7.0) {
    const Pose2 pose = scenario->road.at(s);
    renderer.visible_markings(pose, 3.0, 25.0, {}, clear);
    for (const VisibleMarking& v : clear) {
      if (v.ahead_m < 10.0) continue;
      // A car half way to the marking, in line with it, hides it.
      const auto& m = scenario->markings[v.id];
      const Pose2 local = compose(inverse(pose), Pose2{m.x, m.y, 0.0});
      const Occluder car{v.ahead_m / 2, local.y / 2, 1.8, 1.5};
      renderer.visible_markings(pose, 3.0, 25.0, std::span<const Occluder>(&car, 1), hidden);
      bool listed = false;
      for (const VisibleMarking& h : hidden) listed = listed || h.id == v.id;
      CHECK_FALSE(listed);
      ++compared;
    }
  }
  CHECK(compared > 10);
}

TEST_CASE("a drive that cannot be written says where") {
  const auto file = scratch("not-a-folder");
  std::filesystem::create_directories(file.parent_path());
  std::ofstream(file) << "a file where the drive's folder should be\n";
  const auto scenario = make_scenario("loop", 1);
  const auto recorded = record_drive(*scenario, camera(), short_drive(file / "drive", 1));
  REQUIRE_FALSE(recorded);
  CHECK(recorded.message().starts_with((file / "drive").string() + ": cannot create the directory: "));
  TrainingSetOptions o;
  o.out_dir = (file / "set").string();
  o.frames = 1;
  o.progress = false;
  const auto set = record_training_set(camera(), o);
  REQUIRE_FALSE(set);
  CHECK(set.message().starts_with((file / "set" / "images").string() + ": cannot create the directory: "));
  std::filesystem::remove(file);
}
