// The text files the host tools read (markloop-replay: the paper's marking
// centroids, KITTI poses, the simulator's frames.csv; markloop-eval: the
// ECU's CAN log): any bytes load or give an error naming the file.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "app/tools/eval/can_log.hpp"
#include "app/tools/replay/paper_format.hpp"
#include "tests/fuzz/fuzz_input.hpp"

using namespace markloop;

namespace {

void expect_named(bool loaded, const std::string& error, const std::string& path) {
  if (!loaded && error.rfind(path, 0) != 0) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const fuzz::InputFile file(data, size, ".txt");
  const std::string& path = file.path();
  std::string error;
  std::vector<replay::MarkingRecord> markings;
  expect_named(replay::load_markings(path, markings, error), error, path);
  std::vector<Pose2> poses;
  error.clear();
  expect_named(replay::load_kitti_poses(path, poses, error), error, path);
  std::vector<double> times;
  poses.clear();
  error.clear();
  expect_named(replay::load_truth(path, poses, error, &times), error, path);
  const Result<eval::EcuCanLog> log = eval::read_ecu_can_log(path);
  expect_named(log.ok(), log.ok() ? std::string() : log.message(), path);
  return 0;
}
