#include <catch2/catch_test_macros.hpp>
#include <catch2/matchers/catch_matchers_floating_point.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>

#include "sim/route.hpp"

using namespace markloop::sim;
using Catch::Matchers::WithinAbs;

namespace {
std::string write(const std::string& name, const std::string& text) {
  const auto dir = std::filesystem::temp_directory_path() / "markloop-sim-route-tests";
  std::filesystem::create_directories(dir);
  const auto path = (dir / name).string();
  std::ofstream(path) << text;
  return path;
}

// The message of a route file that load_route refuses ("" when it loads).
std::string refusal(const std::string& path) {
  const auto route = load_route(path);
  return route ? std::string() : route.message();
}

std::string kitti_line(double forward, double right) {
  return "1 0 0 " + std::to_string(right) + " 0 1 0 0 0 0 1 " + std::to_string(forward) + "\n";
}
}  // namespace

TEST_CASE("KITTI routes: the ground is the camera's x-z plane, 10 Hz") {
  std::string text;
  for (int i = 0; i <= 100; ++i) text += kitti_line(i * 1.0, 0.0);  // 100 m straight ahead
  const auto path = write("straight.txt", text);
  const auto route = load_route(path);
  REQUIRE(route);
  CHECK(route->format == RouteFormat::kKitti);
  CHECK(route->poses == 101);
  CHECK_THAT(route->path.length(), WithinAbs(100.0, 0.6));
  CHECK_THAT(route->average_speed_mps(), WithinAbs(10.0, 0.1));
  const auto end = route->path.at(route->path.length());
  CHECK_THAT(end.x, WithinAbs(100.0, 0.6));  // camera z: ahead
  CHECK_THAT(end.y, WithinAbs(0.0, 1e-6));
  CHECK_THAT(end.yaw, WithinAbs(0.0, 1e-6));

  // Camera x is to the right: a route drifting right goes to negative y.
  std::string right;
  for (int i = 0; i <= 100; ++i) right += kitti_line(i * 1.0, i * 0.2);
  const auto r = load_route(write("right.txt", right));
  REQUIRE(r);
  CHECK(r->path.at(r->path.length()).y < -15.0);
}

TEST_CASE("TUM routes: x-y ground, speed from the time stamps") {
  std::string text = "# timestamp tx ty tz qx qy qz qw\n";
  for (int i = 0; i <= 50; ++i)
    text += std::to_string(100.0 + i * 0.5) + " 0 " + std::to_string(i * 2.0) + " 0 0 0 0 1\n";
  const auto route = load_route(write("tum.txt", text));
  REQUIRE(route);
  CHECK(route->format == RouteFormat::kTum);
  CHECK_THAT(route->path.length(), WithinAbs(100.0, 0.6));
  CHECK_THAT(route->average_speed_mps(), WithinAbs(4.0, 0.05));
  CHECK_THAT(route->path.at(50.0).yaw, WithinAbs(std::numbers::pi / 2, 1e-6));
}

TEST_CASE("bad route files are refused with FILE:LINE and the reason") {
  std::string error;
  const auto expect = [&](const std::string& name, const std::string& text, const std::string& what) {
    const auto path = write(name, text);
    error = refusal(path);
    INFO(error);
    CHECK_FALSE(error.empty());
    CHECK(error.find(path + what) == 0);
  };
  expect("nan.txt", kitti_line(0, 0) + "1 0 0 x 0 1 0 0 0 0 1 2\n", ":2: 'x' is not a number");
  expect("count.txt", "# comment\n\n1 2 3 4 5\n", ":3: expected 12 numbers (KITTI 3x4 pose) or 8");
  expect("mixed.txt", kitti_line(0, 0) + kitti_line(1, 0) + "1 2 3 4 5 6 7 8\n",
         ":3: expected 12 numbers like the first pose (KITTI), found 8");
  expect("time.txt", "1 0 0 0 0 0 0 1\n2 1 0 0 0 0 0 1\n2 2 0 0 0 0 0 1\n",
         ":3: timestamp 2.000000 does not increase");
  expect("one.txt", kitti_line(0, 0), ": a route needs at least 2 poses, found 1");
  expect("short.txt", kitti_line(0, 0) + kitti_line(1, 0), ": the route is only");
  CHECK(refusal("/nonexistent/route.txt") ==
        "/nonexistent/route.txt: cannot open: No such file or directory");
}

TEST_CASE("routes that imply no real drive are refused before a world is laid") {
  std::string error;
  const auto expect = [&](const std::string& name, const std::string& text, const std::string& what) {
    const auto path = write(name, text);
    error = refusal(path);
    INFO(error);
    CHECK_FALSE(error.empty());
    CHECK(error == path + what);
  };
  expect("jump.txt", kitti_line(0, 0) + kitti_line(10, 0) + kitti_line(1e7, 0),
         ":3: 10000 km from the pose before: more than the 1000 m a route may step");
  expect("far.txt", kitti_line(0, 0) + "1 0 0 0 0 1 0 0 0 0 1 1e12\n",
         ":2: position (1000000000 km, 0 m) lies beyond 100000 km of the origin");
  expect("tum-far.txt", "0 0 0 0 0 0 0 1\n1 0 -2e8 0 0 0 0 1\n",
         ":2: position (0 m, -200000 km) lies beyond 100000 km of the origin");
  // 101 km in steps of 1 km: the line that takes it past 100 km is named.
  std::string long_route;
  for (int i = 0; i <= 101; ++i) long_route += kitti_line(i * 1000.0, 0.0);
  expect("long.txt", long_route, ":102: the route grows longer than 100 km here");

  // A 90 km drive in steps of a metre, as a real dataset's, is a route.
  std::string drive;
  for (int i = 0; i <= 90000; ++i)
    drive += kitti_line(i % 2000 < 1000 ? i % 1000 : 1000 - i % 1000, 0.1 * (i / 1000));
  CHECK(refusal(write("ninety.txt", drive)) == "");

  const auto dir = std::filesystem::temp_directory_path().string();
  CHECK(refusal(dir) == dir + ": is a directory, not a route file");
  const auto huge = write("huge.txt", "");
  std::filesystem::resize_file(huge, kMaxRouteBytes + 1);  // sparse: nothing written
  CHECK(refusal(huge) == huge + ": larger than 64 MiB, the limit for a route file");
  std::filesystem::remove(huge);
  CHECK(refusal("/dev/zero") == "/dev/zero: larger than 64 MiB, the limit for a route file");
}
