#include <catch2/catch_test_macros.hpp>
#include <catch2/matchers/catch_matchers_string.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "app/tools/replay/paper_format.hpp"
#include "tests/support/result_checks.hpp"

using namespace markloop::replay;
using Catch::Matchers::ContainsSubstring;
using markloop::test::error_of;
using markloop::test::loaded;

namespace {

std::string write_temp(const std::string& name, const std::string& content) {
  const auto path = std::filesystem::temp_directory_path() / ("markloop-test-" + name);
  std::ofstream(path) << content;
  return path.string();
}
}  // namespace

TEST_CASE("markings in the paper's format load", "[format]") {
  const auto path = write_temp("ok.txt", "3\n0 1.5 1.6 10 forward\n4 -2 1.6 12.25 35\n4 +1 1.6 3e1 ped\n");
  std::vector<MarkingRecord> records;
  std::string error;
  records = loaded(load_markings(path));
  REQUIRE(records.size() == 3);
  CHECK(records[1].frame == 4);
  CHECK(records[1].z == 12.25f);
  CHECK(records[1].label == "35");
  CHECK(records[2].z == 30.0f);
  CHECK(records[2].line == 4);
  const auto ground = to_ground(records[0], 0);
  CHECK(ground.x == 10.0f);  // ahead = z
  CHECK(ground.y == -1.5f);  // left = -x
}

TEST_CASE("bad marking files are reported with file and line", "[format]") {
  std::vector<MarkingRecord> records;
  std::string error;
  error = error_of(load_markings("/nonexistent/markings.txt"));
  CHECK_THAT(error, ContainsSubstring("/nonexistent/markings.txt") && ContainsSubstring("cannot open"));

  const auto short_file = write_temp("short.txt", "3\n0 1 2 3 A\n1 1 2 3 B\n");
  error = error_of(load_markings(short_file));
  CHECK_THAT(error, ContainsSubstring(short_file + ":4:") && ContainsSubstring("declares 3 records"));

  const auto long_file = write_temp("long.txt", "1\n0 1 2 3 A\n1 1 2 3 B\n");
  error = error_of(load_markings(long_file));
  CHECK_THAT(error, ContainsSubstring(long_file + ":3:") && ContainsSubstring("more data"));

  const auto bad_number = write_temp("nan.txt", "2\n0 1 2 3 A\n1 1 two 3 B\n");
  error = error_of(load_markings(bad_number));
  CHECK_THAT(error, ContainsSubstring(bad_number + ":3:") && ContainsSubstring("'two'"));

  const auto bad_frame = write_temp("frame.txt", "1\n-1 1 2 3 A\n");
  error = error_of(load_markings(bad_frame));
  CHECK_THAT(error, ContainsSubstring(":2:") && ContainsSubstring("frame index"));

  const auto bad_count = write_temp("count.txt", "many\n");
  error = error_of(load_markings(bad_count));
  CHECK_THAT(error, ContainsSubstring(":1:") && ContainsSubstring("number of records"));

  const auto empty = write_temp("empty.txt", "");
  error = error_of(load_markings(empty));
}

TEST_CASE("an empty record list is valid", "[format]") {
  std::vector<MarkingRecord> records;
  std::string error;
  records = loaded(load_markings(write_temp("zero.txt", "0\n")));
  CHECK(records.empty());
}

TEST_CASE("KITTI poses convert to the ground frame", "[format]") {
  // Camera at x=-2 (right is +x, so 2 m left), z=10 ahead, yawed 90 deg left:
  // the camera's z axis points along world -x.
  const auto path = write_temp("poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n0 0 -1 -2 0 1 0 0 1 0 0 10\n");
  std::vector<markloop::Pose2> poses;
  std::string error;
  poses = loaded(load_kitti_poses(path));
  REQUIRE(poses.size() == 2);
  CHECK(poses[1].x == 10.0);
  CHECK(poses[1].y == 2.0);
  CHECK(std::abs(poses[1].yaw - 1.5707963) < 1e-6);

  const auto short_line = write_temp("short-pose.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1\n");
  error = error_of(load_kitti_poses(short_line));
  CHECK_THAT(error, ContainsSubstring(short_line + ":2:") && ContainsSubstring("found 6"));
}

TEST_CASE("ground truth loads from the simulator's frames.csv", "[format]") {
  const auto path = write_temp("frames.csv", "frame,t,x,y,yaw\n0,0,1,2,0.5\n1,0.1,2,2,0.5\n");
  std::vector<markloop::Pose2> truth;
  std::string error;
  truth = loaded(load_truth(path)).poses;
  REQUIRE(truth.size() == 2);
  CHECK(truth[1].x == 2.0);
  const auto gap = write_temp("gap.csv", "frame,t,x,y,yaw\n0,0,1,2,0.5\n5,0.1,2,2,0.5\n");
  error = error_of(load_truth(gap));
  CHECK_THAT(error, ContainsSubstring(gap + ":3:"));
}
