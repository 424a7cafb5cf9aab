// SIGTERM and SIGINT on the real program: the map is saved and the exit is clean.
#include <catch2/catch_test_macros.hpp>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "app/ecu/config.hpp"
#include "app/ecu/map_store.hpp"
#include "app/io/y4m.hpp"
#include "app/perception/camera_model.hpp"
#include "drivers/can/candump_log.hpp"
#include "tests/ecu/ecu_test_support.hpp"
#include "tests/ecu/notify_listener.hpp"

using namespace markloop;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

namespace {

// A 60 s recording (600 blank frames would be 400 MB: 20 frames at 1/3 fps
// keep the file small while --realtime makes the run last a minute).
void write_recording(const fs::path& dir) {
  const auto camera = perception::default_camera_model();
  io::Y4mWriter video;
  REQUIRE(video.open((dir / "frames.y4m").string(), camera.width(), camera.height(), 1, 3));
  std::vector<std::uint8_t> grey(static_cast<std::size_t>(camera.width()) * camera.height(), 90);
  for (int i = 0; i < 20; ++i) REQUIRE(video.write_frame(grey));
  REQUIRE(video.close());
  can::CandumpLogWriter log;
  REQUIRE_FALSE(log.open((dir / "odometry.log").string().c_str(), "vcan0"));
  ecu::testing::Gateway gateway;
  for (int i = 0; i < 3000; ++i) {
    can::CanFrame frame = gateway.odometry(10.0, 0.0);
    frame.timestamp_ns = std::max<std::int64_t>(1, std::int64_t{i} * 20'000'000);
    REQUIRE_FALSE(log.send(frame));
  }
  REQUIRE_FALSE(log.close());
}

// Runs the ECU on the recording, signals it once it says it is ready (as it
// would tell systemd), and returns its exit status; `after_signal`: how long
// it took to exit then.
int run_and_signal(const fs::path& dir, int signal_number, const fs::path& map,
                   std::chrono::steady_clock::duration& after_signal) {
  const ecu::testing::NotifyListener ready((dir / "notify.sock").string());
  const pid_t pid = fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    ::setenv("NOTIFY_SOCKET", ready.path.c_str(), 1);
    const std::string frames = (dir / "frames.y4m").string(), odometry = (dir / "odometry.log").string();
    const std::string out = (dir / "out.log").string(), map_path = map.string();
    std::vector<std::string> args;
#ifdef MARKLOOP_EMULATOR
    // Cross build: "qemu-<arch>|-L|<root>" in front of the target binary.
    std::string emulator = MARKLOOP_EMULATOR;
    for (std::size_t start = 0, end; start <= emulator.size(); start = end + 1) {
      end = std::min(emulator.find('|', start), emulator.size());
      args.push_back(emulator.substr(start, end - start));
    }
#endif
    for (const char* a :
         {MARKLOOP_BINARY, "--camera-file", frames.c_str(), "--can-in", odometry.c_str(), "--can-out",
          out.c_str(), "--map", map_path.c_str(), "--realtime", "--quiet", "--set", "realtime.mlockall=false",
          "--set", "database.landmark_capacity=1024", "--set", "database.sequence_capacity=1024"})
      args.emplace_back(a);
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  // A fixed pause raced the start-up under the sanitizers on a busy machine:
  // a signal before the ECU blocks it kills the process instead.
  const std::string message = ready.receive(60s);
  if (message != "READY=1") {
    kill(pid, SIGKILL);
    waitpid(pid, nullptr, 0);
  }
  REQUIRE(message == "READY=1");
  std::this_thread::sleep_for(200ms);  // a few frames in, far from the end
  const auto signalled = std::chrono::steady_clock::now();
  REQUIRE(kill(pid, signal_number) == 0);
  int status = 0;
  REQUIRE(waitpid(pid, &status, 0) == pid);
  after_signal = std::chrono::steady_clock::now() - signalled;
  REQUIRE(WIFEXITED(status));
  return WEXITSTATUS(status);
}

}  // namespace

TEST_CASE("SIGTERM and SIGINT save the map and exit 0") {
  const fs::path dir = fs::temp_directory_path() / "markloop-signal-test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  write_recording(dir);
  for (const int signal_number : {SIGTERM, SIGINT}) {
    INFO("signal " << signal_number);
    const fs::path map = dir / ("map-" + std::to_string(signal_number) + ".bin");
    std::chrono::steady_clock::duration after_signal{};
    CHECK(run_and_signal(dir, signal_number, map, after_signal) == 0);
    CHECK(after_signal < 10s);  // not the rest of the minute
    REQUIRE(fs::exists(map));
    MatchConfig match;
    DatabaseConfig capacity;
    capacity.landmark_capacity = capacity.sequence_capacity = 1024;
    SequenceDatabase db(capacity, match, ecu::ecu_engine_defaults().chain.k);
    ecu::MapStore store(map.string());
    CHECK(store.load(db, match).outcome == ecu::MapLoadOutcome::kLoaded);
    CHECK(fs::exists(dir / "out.log"));
  }
}
