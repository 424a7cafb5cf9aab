// The two ways the ECU runs: on recorded files (laptop, CI, evaluation) and
// live on devices (car, HIL VM). Both build the same Ecu, start it the same
// way (map, memory lock, real-time priority) and stop cleanly on SIGTERM or
// SIGINT (map saved).
#pragma once

#include <string>

#include "app/ecu/config.hpp"
#include "app/ecu/ecu.hpp"
#include "app/perception/camera_model.hpp"
#include "app/perception/marking_detector.hpp"
#include "platform/os.hpp"
#include "platform/unique_fd.hpp"

namespace markloop::ecu {

struct RunOptions {
  EcuConfig config;
  perception::CameraModel camera = perception::default_camera_model();
  perception::DetectorConfig detector;
  std::string summary_json;  // where to write the run's figures; empty: none
  bool quiet = false;        // no summary on stderr
};

// Exit status: 0 after a clean end (end of files, SIGTERM, SIGINT); 1 when an
// output, the map or the summary could not be written; 2 for bad input or
// configuration (also an input found damaged during the run).
int run_file_mode(const RunOptions& options);
int run_live_mode(const RunOptions& options);

// Shared by both runners.
namespace detail {
// Blocks SIGTERM/SIGINT and returns a signalfd for them (exits 2 on failure).
platform::UniqueFd open_stop_signals();
// 0 when none is pending, else the signal number.
int pending_stop_signal(int signal_fd);
// Loads the map, then locks memory and raises priority as configured; reports
// on stderr. False when the map must not be used (the program exits 2).
bool start_up(Ecu& ecu, const EcuConfig& config, bool quiet);
// The sd_notify channel of $NOTIFY_SOCKET (a no-op without one); a socket
// that cannot be used is reported on stderr, never fatal.
platform::SystemdNotifier open_systemd_notifier();
// Saves the map when configured; false (reported on stderr) when that failed.
bool shut_down(Ecu& ecu, const EcuConfig& config, bool quiet);
// Figures of the run on stderr and, when asked, as JSON; false (reported on
// stderr) when the JSON could not be written.
bool report(const Ecu& ecu, const RunOptions& options, double wall_seconds, const char* mode);
}  // namespace detail

}  // namespace markloop::ecu
