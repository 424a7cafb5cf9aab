// Configuration file parsing: every error names FILE:LINE and what is wrong.
#include <catch2/catch_test_macros.hpp>
#include <catch2/matchers/catch_matchers_string.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "app/ecu/config.hpp"

using Catch::Matchers::ContainsSubstring;
using Catch::Matchers::StartsWith;
using markloop::ecu::EcuConfig;
using markloop::ecu::load_config_file;

namespace {
std::string write_temp(const std::string& name, const std::string& text) {
  const auto path = std::filesystem::temp_directory_path() / ("markloop-config-test-" + name);
  std::ofstream(path) << text;
  return path.string();
}

// The error of loading `path`, empty when it loads.
std::string load_error(const std::string& path, EcuConfig& config) {
  const markloop::Status status = load_config_file(path, config);
  return status ? std::string() : status.message();
}

std::string validate_error(const EcuConfig& config) {
  const markloop::Status status = markloop::ecu::validate_config(config);
  return status ? std::string() : status.message();
}
}  // namespace

TEST_CASE("config file sets keys, ignores comments and blank lines") {
  const std::string path = write_temp("ok.conf",
                                      "# comment\n\n  camera.device = /dev/video3  # trailing\n"
                                      "engine.k=5\ncan.interface = vcan0\nrealtime.mlockall = no\n"
                                      "database.sequence_capacity = 4096\n");
  EcuConfig config;
  REQUIRE(load_error(path, config).empty());
  CHECK(config.camera.device == "/dev/video3");
  CHECK(config.engine.chain.k == 5);
  CHECK(config.can.interface == "vcan0");
  CHECK_FALSE(config.realtime.lock_memory);
  CHECK(config.engine.database.sequence_capacity == 4096);
  CHECK(validate_error(config).empty());
}

TEST_CASE("config errors carry file, line and the problem") {
  EcuConfig config;
  std::string path = write_temp("unknown.conf", "engine.k = 4\nno.such.key = 1\n");
  CHECK_THAT(load_error(path, config), StartsWith(path + ":2: unknown key 'no.such.key'"));

  path = write_temp("noequals.conf", "\n\ncamera.device /dev/video0\n");
  CHECK_THAT(load_error(path, config), StartsWith(path + ":3: expected 'key = value'"));

  path = write_temp("range.conf", "engine.k = 11\n");
  CHECK_THAT(load_error(path, config), StartsWith(path + ":1: engine.k: must be between 2 and 10"));

  path = write_temp("number.conf", "status.period_ms = fast\n");
  CHECK_THAT(load_error(path, config), ContainsSubstring(":1: status.period_ms: not a whole number"));

  path = write_temp("real.conf", "engine.distance_tolerance_m = 0.5m\n");
  CHECK_THAT(load_error(path, config), ContainsSubstring(":1: engine.distance_tolerance_m: not a number"));

  path = write_temp("bool.conf", "realtime.mlockall = maybe\n");
  CHECK_THAT(load_error(path, config), ContainsSubstring(":1: realtime.mlockall: not true/false"));

  path = write_temp("format.conf", "camera.format = rgb\n");
  CHECK_THAT(load_error(path, config), ContainsSubstring("must be grey or yuyv"));

  path = write_temp("emptykey.conf", " = 3\n");
  CHECK_THAT(load_error(path, config), ContainsSubstring(":1: missing key"));

  CHECK_THAT(load_error("/nonexistent/markloop.conf", config),
             StartsWith("/nonexistent/markloop.conf: cannot open"));
}

TEST_CASE("validate_config rejects half a file mode and bad engine settings") {
  EcuConfig config;
  config.camera.file = "frames.y4m";
  CHECK_THAT(validate_error(config), ContainsSubstring("both a frame file"));
  config.can.in_log = "odometry.log";
  CHECK(validate_error(config).empty());
  config.engine.chain.max_link_m = 1.0;  // not above the row width
  CHECK_THAT(validate_error(config), StartsWith("engine: "));
  EcuConfig live;
  live.realtime_replay = true;
  CHECK_THAT(validate_error(live), ContainsSubstring("file mode only"));
}

TEST_CASE("the shipped markloop.conf parses and every key round-trips") {
  EcuConfig config;
  REQUIRE(load_error(MARKLOOP_SOURCE_DIR "/app/ecu/markloop.conf", config).empty());
  CHECK(config.map_file == "/var/lib/markloop/map.bin");
  // format_config() prints every key; reading it back gives the same text.
  const std::string printed = markloop::ecu::format_config(config);
  EcuConfig again;
  REQUIRE(load_error(write_temp("printed.conf", printed), again).empty());
  CHECK(markloop::ecu::format_config(again) == printed);
}
