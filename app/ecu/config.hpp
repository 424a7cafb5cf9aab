// The ECU's configuration: one key = value file (markloop.conf, documented
// there) that command-line flags override. Parsed once at start-up; nothing
// here runs in the real-time loop.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "app/common/result.hpp"
#include "app/engine/config.hpp"
#include "app/engine/types.hpp"

namespace markloop::ecu {

enum class PixelFormat : std::uint8_t { kGrey, kYuyv };

struct CameraSettings {
  std::string device = "/dev/video0";  // live capture node
  std::string file;                    // frame file (.y4m); set: file mode
  int input = -1;                      // V4L2 input index; -1 keeps the current one
  PixelFormat format = PixelFormat::kGrey;
  unsigned width = 1280;  // must match the calibration
  unsigned height = 512;
  unsigned fps = 10;           // 0: the driver's rate (HDMI-like inputs); deadlines as 10
  unsigned timeout_ms = 500;   // no frame this long: camera lost
  unsigned max_rate = 0;       // process at most this many frames per second (0: all)
  unsigned blind_frames = 10;  // this many frames in a row showing no road: camera blind
};

struct CanSettings {
  std::string interface = "can0";  // live SocketCAN interface
  std::string in_log;              // candump -l log to read; set: file mode
  std::string out_log;             // candump -l log of everything sent
};

struct RealtimeSettings {
  int priority = 0;         // SCHED_FIFO priority 1..99; 0 keeps the default scheduler
  int cpu = -1;             // CPU to pin the loop to; -1 any
  bool lock_memory = true;  // mlockall(MCL_CURRENT | MCL_FUTURE) after start-up
};

// Which detections become observations for the engine (all are reported in
// the detections CSV): markings cut by the image border (near, far) are
// placed poorly, and low classifier confidence is mostly clutter. Why the
// score gate has its value: docs/decisions.md. main() refuses a gate below
// the detector's own threshold (detector_min_score): nothing under it is
// detected.
struct ObservationGate {
  float min_score = 0.6f;
  float min_range_m = 5.5f;  // ahead of the vehicle reference point
  float max_range_m = 16.0f;
};

// The engine's settings in the car, where they differ from the engine's own
// defaults (why: the descriptions in settings.cpp and docs/decisions.md):
// more sightings keep single-frame clutter out, the odometry prior and the
// frame distance reject look-alike places, loaded places need confirming,
// a loose match would give a poor relative pose, places close loops where
// the sequences cannot (turns into old roads, the other direction), visits
// far apart need a longer run, and landmarks join the chains and places as
// soon as they have left view, in order, before the car reaches them, so that
// a loop closes as soon as its last marking is committed. k stays at the
// engine's: shorter sequences let look-alike city blocks confirm wrong
// alignments across sessions.
inline EngineConfig ecu_engine_defaults() {
  EngineConfig c;
  c.tracker.min_observations = 3;
  c.tracker.release_lag_m = 5.0;
  c.tracker.settled_lag_m = -20.0;
  c.match.max_residual_m = 0.3;
  c.match.max_drift_rel = 0.02;
  c.match.max_frame_distance_m = 4.0;
  c.match.confirm_loaded_places = true;
  c.match.place_landmarks = 3;
  c.match.far_run_m = 300.0;
  c.match.place_within_m = 2000.0;
  c.match.place_opposite_within_m = 1200.0;
  c.match.place_min_bits = 6.0;
  c.match.place_pair_min_bits = 4.0;
  c.match.place_pair_max_unseen = 0;
  c.match.place_max_residual_m = 0.14;
  return c;
}

struct EcuConfig {
  CameraSettings camera;
  CanSettings can;
  std::string calibration;  // camera calibration YAML; empty: the simulator's default
  std::string map_file;     // place database; empty: none kept
  bool save_map_on_exit = true;
  std::string detections_out;  // CSV of every detection (file mode, evaluation)
  std::string landmarks_out;   // CSV of the landmarks this run made (file mode, at the end; evaluation)
  unsigned status_period_ms = 100;
  unsigned odometry_timeout_ms = 60;  // three cycles of VehicleOdometry
  bool realtime_replay = false;       // file mode: pace frames to the recorded rate
  // File mode: process frames [first_frame, first_frame + frame_count) of the
  // recording (0: to the end); odometry before first_frame still moves the
  // pose. One recording can so be split into drives (map saved in between).
  std::uint64_t first_frame = 0;
  std::uint64_t frame_count = 0;
  RealtimeSettings realtime;
  ObservationGate gate;
  EngineConfig engine = ecu_engine_defaults();

  bool file_mode() const { return !camera.file.empty(); }
};

// Sets one key from its text value (keys, ranges: settings.hpp), or says
// what is wrong ("KEY: what", "unknown key 'KEY'").
Status set_config_value(EcuConfig& config, std::string_view key, std::string_view value);

// Larger files are no configuration (the shipped one is a few kB).
inline constexpr std::size_t kMaxConfigFileBytes = std::size_t{1} << 20;

// Reads a key = value file ('#' starts a comment, blank lines ignored) into
// `config`, or says "FILE:LINE: what is wrong".
Status load_config_file(const std::string& path, EcuConfig& config);

// Checks the combination (files vs devices, engine limits) and says what is
// wrong when it is not usable.
Status validate_config(const EcuConfig& config);

// Every key with its current value, one "key = value" per line (for --print-config).
std::string format_config(const EcuConfig& config);

// One key's current value as format_config() prints it; empty for an unknown key.
std::string format_config_value(const EcuConfig& config, std::string_view key);

}  // namespace markloop::ecu
