// Every test process gets a temporary directory of its own: TMPDIR is set to
// a fresh directory named after the process before the first test case runs,
// and removed after the last. Tests name their scratch files after
// std::filesystem::temp_directory_path(), so two test runs at once (two build
// trees, two presets, tests run in parallel) never share a file.
#include <unistd.h>

#include <catch2/catch_test_case_info.hpp>
#include <catch2/reporters/catch_reporter_event_listener.hpp>
#include <catch2/reporters/catch_reporter_registrars.hpp>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <system_error>

namespace {

class ScratchTmpdir : public Catch::EventListenerBase {
 public:
  using Catch::EventListenerBase::EventListenerBase;

  void testRunStarting(const Catch::TestRunInfo&) override {
    const char* parent = std::getenv("TMPDIR");
    dir_ = std::filesystem::path(parent != nullptr && *parent != '\0' ? parent : "/tmp") /
           ("markloop-test-" + std::to_string(::getpid()));
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
    std::filesystem::create_directories(dir_, ec);
    if (!ec) ::setenv("TMPDIR", dir_.c_str(), 1);
  }

  void testRunEnded(const Catch::TestRunStats&) override {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }

 private:
  std::filesystem::path dir_;
};

}  // namespace

CATCH_REGISTER_LISTENER(ScratchTmpdir)
