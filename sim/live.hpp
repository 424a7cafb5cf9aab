// Live mode: plays a recorded drive (frames.y4m + odometry.log, as written
// by `markloop-sim drive`) into real devices in real time, for
// hardware-in-the-loop tests: frames into a V4L2 output node (vivid's output,
// looped back into its capture node, which the ECU reads) and odometry onto a
// SocketCAN interface. Every event is sent at its absolute deadline
// (clock_nanosleep TIMER_ABSTIME on CLOCK_MONOTONIC from the start), so
// lateness does not accumulate.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "app/common/result.hpp"
#include "drivers/v4l2/v4l2_format.hpp"

namespace markloop::sim {

struct LiveOptions {
  std::string drive_dir;     // frames.y4m and odometry.log
  std::string video_device;  // e.g. /dev/video1 (vivid output)
  int video_output = -1;     // VIDIOC_S_OUTPUT index; -1 keeps the current one
  v4l2::PixelFormat format = v4l2::PixelFormat::Grey;
  std::string can_interface;   // e.g. vcan0; empty: no CAN
  std::size_t max_frames = 0;  // 0: the whole drive
  bool progress = true;
};

struct LiveCounters {
  std::uint64_t frames_sent = 0;
  std::uint64_t frame_errors = 0;  // V4L2 refused or timed out
  std::uint64_t can_sent = 0;
  std::uint64_t can_errors = 0;
  std::uint64_t late_events = 0;  // sent more than 5 ms after their deadline
  double max_lateness_ms = 0.0;
  bool interrupted = false;  // SIGINT/SIGTERM
};

// The odometry log is read whole, up to this limit (checked first): more
// than a day of driving at the odometry's 50 Hz.
inline constexpr std::size_t kMaxOdometryBytes = std::size_t{256} << 20;

// The run's counters, or an error when the drive cannot be read or a device
// cannot be opened; send failures during the run are counted, not fatal.
Result<LiveCounters> run_live(const LiveOptions& options);

}  // namespace markloop::sim
