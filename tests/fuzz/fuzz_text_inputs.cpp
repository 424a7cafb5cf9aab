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

// A load that failed must name the file first.
template <class T>
void expect_named(const Result<T>& loaded, const std::string& path) {
  if (!loaded && loaded.message().rfind(path, 0) != 0) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const fuzz::InputFile file(data, size, ".txt");
  const std::string& path = file.path();
  expect_named(replay::load_markings(path), path);
  expect_named(replay::load_kitti_poses(path), path);
  expect_named(replay::load_truth(path), path);
  expect_named(eval::read_ecu_can_log(path), path);
  return 0;
}
