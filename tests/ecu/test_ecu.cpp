// The ECU's loop logic with fake devices: loop detections on the bus, and
// every degraded state visible in Status.
#include <catch2/catch_test_macros.hpp>

#include <filesystem>
#include <fstream>

#include "app/ecu/ecu.hpp"
#include "app/perception/camera_model.hpp"
#include "tests/ecu/ecu_test_support.hpp"
#include "tests/perception/synthetic_road.hpp"

using namespace markloop;
using namespace markloop::ecu;
using namespace markloop::ecu::testing;
using namespace std::chrono_literals;

namespace {

EcuConfig test_config() {
  EcuConfig c;
  c.engine.database.landmark_capacity = 4096;
  c.engine.database.sequence_capacity = 16384;
  c.camera.fps = 10;
  return c;
}

struct DriveOptions {
  Nanoseconds odometry_gap_from{Nanoseconds::max()};
  Nanoseconds odometry_gap_to{Nanoseconds::max()};
  unsigned foreign_per_odometry = 0;  // foreign frames around each odometry frame
  unsigned corrupt_every = 0;         // every Nth odometry frame has a bad CRC
};

// Drives the loop road from `from` to `to`: odometry every 20 ms, a frame
// every 100 ms, Status every 100 ms, all in time order.
struct Driver {
  explicit Driver(Ecu& e) : ecu(e) {}
  Ecu& ecu;
  Gateway gateway;
  LoopRoad road;
  std::array<perception::Detection, perception::kMaxDetections> detections{};
  Nanoseconds t{0};

  void drive(Nanoseconds to, const DriveOptions& o = {}) {
    std::uint64_t odometry_count = 0;
    for (; t < to; t += 20ms) {
      const bool in_gap = t >= o.odometry_gap_from && t < o.odometry_gap_to;
      if (!in_gap) {
        for (unsigned i = 0; i < o.foreign_per_odometry; ++i) {
          can::CanFrame foreign;
          foreign.id = 0x300 + (i % 0x500);  // everything but our ids
          foreign.dlc = 8;
          ecu.on_can_frame(foreign, t);
        }
        can::CanFrame frame = gateway.odometry(LoopRoad::kSpeed, road.yaw_rate());
        if (o.corrupt_every > 0 && ++odometry_count % o.corrupt_every == 0) frame.data[3] ^= 0x40;
        ecu.on_can_frame(frame, t);
      }
      if (t.count() % 100'000'000 == 0) {
        const double seconds = std::chrono::duration<double>(t).count();
        const std::size_t n = road.detections(seconds, detections);
        ecu.on_detections(std::span<const perception::Detection>(detections.data(), n), t,
                          SteadyClock::now());
        ecu.send_status(t);
      }
    }
  }
};

}  // namespace

TEST_CASE("two laps: loop detections reach the bus, E2E-protected, with the relative pose") {
  RecordingBus bus;
  Ecu ecu(test_config(), perception::default_camera_model(), {}, &bus, nullptr);
  Driver driver(ecu);
  driver.drive(260s);  // 2.2 laps
  CHECK(bus.errors == 0);
  CHECK(ecu.counters().loop_detections > 5);
  CHECK(bus.detections == ecu.counters().loop_detections);
  const dbc::LoopDetection& d = bus.last_detection;
  CHECK(d.sequence_length == ecu_engine_defaults().chain.k);
  CHECK(d.pose_valid);
  CHECK(std::abs(d.pose_dx_m) < 0.3);
  CHECK(std::abs(d.pose_dy_m) < 0.3);
  CHECK(std::abs(d.pose_dyaw_deg) < 1.0);
  // The matched place was seen a lap (1200 frames) earlier.
  CHECK(d.query_frame - d.match_frame > 1100);
  CHECK(d.query_frame - d.match_frame < 1300);
  // The detection is stamped after the frame that completed it, and soon.
  CHECK(ecu.detection_latency().count() == ecu.counters().loop_detections);
  CHECK(ecu.detection_latency().max_ns() < 33'000'000);
  CHECK(bus.status.system_state == dbc::SystemState::Running);
  CHECK(bus.status.frames_processed > 2500);
  CHECK(bus.status.landmark_count > 100);
}

TEST_CASE("odometry timeout: pose unknown, no new sequences, Degraded until odometry returns") {
  RecordingBus bus;
  Ecu ecu(test_config(), perception::default_camera_model(), {}, &bus, nullptr);
  Driver driver(ecu);
  driver.drive(60s);
  CHECK_FALSE(bus.status.fault_odometry_timeout);
  DriveOptions gap;
  gap.odometry_gap_from = 60s;
  gap.odometry_gap_to = 90s;
  driver.drive(61s, gap);  // the pose is lost; chains break and flush once
  const auto sequences_at_loss = ecu.engine().counters().sequences_created;
  const auto landmarks_at_loss = ecu.engine().counters().landmarks_released;
  driver.drive(90s, gap);
  CHECK(ecu.engine().counters().sequences_created == sequences_at_loss);
  CHECK(ecu.engine().counters().landmarks_released == landmarks_at_loss);
  CHECK(bus.status.fault_odometry_timeout);
  CHECK(bus.status.system_state == dbc::SystemState::Degraded);
  CHECK(ecu.counters().pose_losses == 1);
  CHECK(ecu.counters().frames_without_pose >= 290);
  CHECK(ecu.odometry().counters().timeouts == 1);
  driver.drive(150s, gap);  // odometry is back
  CHECK_FALSE(bus.status.fault_odometry_timeout);
  CHECK(bus.status.system_state == dbc::SystemState::Running);
  CHECK(ecu.engine().counters().sequences_created > sequences_at_loss);
}

TEST_CASE("odometry with bad CRC is dropped and counted; Status reports a bus error") {
  RecordingBus bus;
  Ecu ecu(test_config(), perception::default_camera_model(), {}, &bus, nullptr);
  Driver driver(ecu);
  DriveOptions o;
  // Every 5th frame: its successor then has a skipped counter and is dropped
  // too, leaving 60 ms gaps, which the timeout still tolerates.
  o.corrupt_every = 5;
  driver.drive(10s, o);
  CHECK(ecu.odometry().counters().bad_crc == 100);
  CHECK(ecu.odometry().counters().bad_counter >= 99);
  CHECK(bus.status.fault_bus_error);
  CHECK(bus.status.system_state == dbc::SystemState::Degraded);
  CHECK(ecu.counters().frames_without_pose <= 1);
  driver.drive(20s);
  CHECK_FALSE(bus.status.fault_bus_error);
}

TEST_CASE("a repeated alive counter is rejected") {
  RecordingBus bus;
  Ecu ecu(test_config(), perception::default_camera_model(), {}, &bus, nullptr);
  Gateway gateway;
  const can::CanFrame frame = gateway.odometry(10, 0);
  ecu.on_can_frame(frame, 0ms);
  ecu.on_can_frame(frame, 20ms);
  ecu.on_can_frame(frame, 40ms);
  CHECK(ecu.odometry().counters().accepted == 1);
  CHECK(ecu.odometry().counters().bad_counter == 2);
  ecu.send_status(50ms);
  CHECK(bus.status.fault_bus_error);
}

TEST_CASE("a flood of foreign frames is counted and changes nothing") {
  RecordingBus bus;
  Ecu ecu(test_config(), perception::default_camera_model(), {}, &bus, nullptr);
  Driver driver(ecu);
  DriveOptions o;
  o.foreign_per_odometry = 200;  // 10,000 frames per second
  driver.drive(30s, o);
  CHECK(ecu.counters().foreign_frames == 200 * 1500);
  CHECK(ecu.odometry().counters().accepted == 1500);
  CHECK(ecu.counters().frames_without_pose <= 1);
  CHECK_FALSE(bus.status.fault_bus_error);
  // Extended frames on our ids are foreign too; short frames on our ids are errors.
  can::CanFrame extended = driver.gateway.odometry(10, 0);
  extended.extended = true;
  ecu.on_can_frame(extended, 30s);
  can::CanFrame oversized = driver.gateway.odometry(10, 0);
  oversized.dlc = 9;
  ecu.on_can_frame(oversized, 30s);
  CHECK(ecu.counters().foreign_frames == 200 * 1500 + 1);
  CHECK(ecu.counters().bad_frames == 1);
}

TEST_CASE("a bus that refuses frames (queue full, bus-off, down) is counted and reported") {
  RecordingBus bus;
  Ecu ecu(test_config(), perception::default_camera_model(), {}, &bus, nullptr);
  Driver driver(ecu);
  driver.drive(5s);
  bus.refuse_with = std::make_error_code(std::errc::no_buffer_space);
  driver.drive(6s);
  CHECK(ecu.counters().send_errors == 10 * dbc::Status::kPages.size());
  bus.refuse_with = {};
  ecu.send_status(6s);
  CHECK(bus.status.fault_bus_error);
  ecu.send_status(6s + 100ms);
  CHECK_FALSE(bus.status.fault_bus_error);
  // The SocketCAN driver in BusOff or Recovering: the runner raises the fault.
  ecu.set_bus_fault(true);
  ecu.send_status(6s + 200ms);
  CHECK(bus.status.fault_bus_error);
  CHECK(bus.status.system_state == dbc::SystemState::Degraded);
  ecu.set_bus_fault(false);
  driver.drive(7s);
  CHECK(bus.status.system_state == dbc::SystemState::Running);
}

TEST_CASE("an overrun frame is counted, the next one is processed, Status shows it") {
  RecordingBus bus;
  Ecu ecu(test_config(), perception::default_camera_model(), {}, &bus, nullptr);
  Driver driver(ecu);
  driver.drive(5s);
  // A frame that reached the loop 150 ms late (longer than a 100 ms period).
  ecu.on_detections({}, 5s, SteadyClock::now() - 150ms);
  ecu.count_dropped_frames(1);  // and one the runner skipped
  ecu.send_status(5s);
  CHECK(ecu.counters().overruns == 1);
  CHECK(bus.status.fault_overrun);
  CHECK(bus.status.frames_dropped == 1);
  CHECK(bus.status.system_state == dbc::SystemState::Degraded);
  driver.drive(6s);
  CHECK_FALSE(bus.status.fault_overrun);
  CHECK(bus.status.frames_dropped == 1);  // a total: stays
}

TEST_CASE("camera lost and back") {
  RecordingBus bus;
  Ecu ecu(test_config(), perception::default_camera_model(), {}, &bus, nullptr);
  Driver driver(ecu);
  driver.drive(2s);
  ecu.set_camera_lost(true);
  ecu.send_status(2s);
  CHECK(bus.status.fault_camera_lost);
  CHECK(bus.status.system_state == dbc::SystemState::Fault);
  ecu.set_camera_lost(false);
  driver.drive(3s);
  CHECK_FALSE(bus.status.fault_camera_lost);
  CHECK(bus.status.system_state == dbc::SystemState::Running);
}

TEST_CASE("a camera that shows no road is blind after camera.blind_frames frames, until as many show road") {
  RecordingBus bus;
  EcuConfig config = test_config();
  config.camera.blind_frames = 5;
  const perception::CameraModel camera = perception::default_camera_model();
  Ecu ecu(config, camera, {}, &bus, nullptr);
  const cv::Mat road =
      perception::testing::render_road(camera, {{3.0, 25.0, 1.7, 1.85}, {3.0, 25.0, -1.85, -1.7}});
  const cv::Mat covered(camera.height(), camera.width(), CV_8UC1, cv::Scalar(3));
  Nanoseconds t{0};
  const auto frames = [&](const cv::Mat& image, int n) {
    for (int i = 0; i < n; ++i) {
      ecu.on_frame(image, t, SteadyClock::now());
      t += 100ms;
      ecu.send_status(t);
    }
  };
  frames(road, 3);
  CHECK_FALSE(bus.status.fault_camera_blind);
  frames(covered, 4);  // a splash on the lens: not yet a fault
  frames(road, 1);
  CHECK_FALSE(bus.status.fault_camera_blind);
  CHECK(bus.status.frames_blind == 4);
  frames(covered, 4);
  CHECK_FALSE(bus.status.fault_camera_blind);
  frames(covered, 1);  // the fifth in a row
  CHECK(bus.status.fault_camera_blind);
  CHECK(bus.status.system_state == dbc::SystemState::Fault);
  CHECK_FALSE(bus.status.fault_camera_lost);
  frames(road, 4);  // road for a moment: still blind
  frames(covered, 1);
  frames(road, 4);
  CHECK(bus.status.fault_camera_blind);
  frames(road, 1);  // the fifth in a row
  CHECK_FALSE(bus.status.fault_camera_blind);
  CHECK(bus.status.system_state != dbc::SystemState::Fault);
  CHECK(bus.status.frames_blind == 10);
  CHECK(ecu.counters().frames_blind == 10);
  CHECK(ecu.detector().counters().flat_frames == 10);
}

TEST_CASE("Command SaveMap writes the map, ResetDatabase empties it, bad commands are refused") {
  const auto dir = std::filesystem::temp_directory_path() / "markloop-ecu-command-test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  EcuConfig config = test_config();
  config.map_file = (dir / "map.bin").string();
  RecordingBus bus;
  Ecu ecu(config, perception::default_camera_model(), {}, &bus, nullptr);
  Driver driver(ecu);
  driver.drive(60s);
  const auto landmarks = ecu.engine().database().stats().landmarks;
  REQUIRE(landmarks > 10);

  ecu.on_can_frame(driver.gateway.command(dbc::CommandCode::SaveMap), 60s);
  CHECK(ecu.counters().map_saves == 1);
  REQUIRE(std::filesystem::exists(dir / "map.bin"));

  Gateway other;  // a frame that does not advance the real gateway's counter
  can::CanFrame corrupted = other.command(dbc::CommandCode::ResetDatabase);
  corrupted.data[2] ^= 0x03;  // bad CRC
  ecu.on_can_frame(corrupted, 60s);
  CHECK(ecu.counters().commands_rejected == 1);
  CHECK(ecu.engine().database().stats().landmarks >= landmarks);

  ecu.on_can_frame(driver.gateway.command(dbc::CommandCode::ResetDatabase), 60s);
  CHECK(ecu.counters().database_resets == 1);
  CHECK(ecu.engine().database().stats().landmarks == 0);

  // The saved map loads into a fresh ECU.
  Ecu second(config, perception::default_camera_model(), {}, &bus, nullptr);
  const MapLoadResult loaded = second.load_map();
  CHECK(loaded.outcome == MapLoadOutcome::kLoaded);
  CHECK(loaded.landmarks >= landmarks);
}

TEST_CASE("a second drive recognises the places of a saved map") {
  const auto dir = std::filesystem::temp_directory_path() / "markloop-ecu-two-drives";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  EcuConfig config = test_config();
  config.map_file = (dir / "map.bin").string();
  {
    RecordingBus bus;
    Ecu first(config, perception::default_camera_model(), {}, &bus, nullptr);
    Driver driver(first);
    driver.drive(115s);  // most of a lap, no revisit
    first.finish(115s);
    CHECK(first.counters().loop_detections == 0);
    REQUIRE_FALSE(first.save_map());
  }
  RecordingBus bus;
  Ecu second(config, perception::default_camera_model(), {}, &bus, nullptr);
  REQUIRE(second.load_map().outcome == MapLoadOutcome::kLoaded);
  Driver driver(second);
  driver.drive(60s);  // half a lap, the first time in this session
  CHECK(second.counters().loop_detections > 3);
  CHECK(bus.last_detection.match_time_s == 0.0);  // the earlier drive's time is not this session's
}
