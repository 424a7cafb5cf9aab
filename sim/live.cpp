#include "sim/live.hpp"

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <string_view>
#include <vector>

#include <linux/videodev2.h>

#include "app/io/y4m.hpp"
#include "app/tools/common/tool_files.hpp"
#include "drivers/can/candump_log.hpp"
#include "drivers/can/socketcan.hpp"
#include "drivers/v4l2/v4l2_device.hpp"
#include "drivers/v4l2/v4l2_output.hpp"

namespace markloop::sim {

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) {
  g_stop = 1;
}

std::int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// Sleeps until the absolute CLOCK_MONOTONIC time `deadline_ns`; false when a
// stop signal arrived first.
bool sleep_until(std::int64_t deadline_ns) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(deadline_ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(deadline_ns % 1'000'000'000);
  while (g_stop == 0) {
    const int rc = clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
    if (rc == 0) return true;
    if (rc != EINTR) return false;
  }
  return false;
}

Result<std::vector<can::CanFrame>> load_odometry(const std::string& path) {
  const Result<std::string> read = tools::read_input(path, kMaxOdometryBytes, "an odometry log");
  if (!read) return read.error();
  const std::string& text = *read;
  std::vector<can::CanFrame> frames;
  tools::Lines lines(text);
  std::string_view line;
  while (lines.next(line)) {
    if (line.empty()) continue;
    const std::string where = path + ":" + std::to_string(lines.number()) + ":";
    can::CandumpRecord record;
    can::CandumpLineError line_error;
    if (!can::parse_candump_line(line, record, line_error))
      return error(where + std::to_string(line_error.column) + ": " + line_error.what);
    if (!frames.empty() && record.frame.timestamp_ns < frames.back().timestamp_ns)
      return error(where + " time stamps go backwards");
    frames.push_back(record.frame);
  }
  return frames;
}

// HDMI-like outputs take only frames of their DV timings' size: select the
// output's timings that match the drive's frame size (vivid's HDMI output
// offers 640x480, 1280x720, ...). Outputs without DV timings are left alone.
std::error_code select_dv_timings(const LiveOptions& options, std::uint32_t width, std::uint32_t height) {
  v4l2::V4l2Device dev;
  v4l2::DeviceInfo info;
  if (auto ec = dev.open(options.video_device.c_str(), v4l2::V4l2Device::Direction::Output, info)) return ec;
  if (options.video_output >= 0)
    if (auto ec = dev.select_output(options.video_output)) return ec;
  for (std::uint32_t index = 0; index < 64; ++index) {
    v4l2_enum_dv_timings e{};
    e.index = index;
    if (dev.ioctl(VIDIOC_ENUM_DV_TIMINGS, &e)) break;  // end of the list, or no DV timings
    if (e.timings.bt.width == width && e.timings.bt.height == height)
      return dev.ioctl(VIDIOC_S_DV_TIMINGS, &e.timings);
  }
  return {};
}

// The bus first: its name is checked before the video device is set up.
Status open_bus(const LiveOptions& options, can::SocketCan& bus) {
  if (options.can_interface.empty()) return {};
  if (const auto ec = bus.open(options.can_interface, {}))
    return error(options.can_interface + ": cannot open: " + ec.message());
  return {};
}

// Starts the V4L2 output for frames of the drive's size.
Status start_output(const LiveOptions& options, const io::Y4mFormat& format, v4l2::V4l2Output& output) {
  v4l2::OutputConfig config;
  config.device = options.video_device;
  config.output = options.video_output;
  config.width = static_cast<std::uint32_t>(format.width);
  config.height = static_cast<std::uint32_t>(format.height);
  config.format = options.format;
  if (const auto ec = select_dv_timings(options, config.width, config.height))
    return error(options.video_device + ": cannot select the output's timings: " + ec.message());
  config.fps = 0;  // the pacing is ours (absolute deadlines); many outputs have no rate to set
  if (const auto ec = output.start(config))
    return error(options.video_device + ": cannot start the V4L2 output: " + ec.message());
  if (output.format().width != config.width || output.format().height != config.height)
    return error(options.video_device + ": the output takes " + std::to_string(output.format().width) + "x" +
                 std::to_string(output.format().height) + ", the drive is " + std::to_string(config.width) +
                 "x" + std::to_string(config.height) +
                 " (record it with a --camera of that size, or select another output)");
  return {};
}

void stop_on_signals() {
  struct sigaction action {};
  action.sa_handler = on_signal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  g_stop = 0;
}

// The drive opened for playing: its frames, its odometry and the devices.
struct Playback {
  io::Y4mReader video;
  std::vector<can::CanFrame> odometry;  // all of it, read before the clock starts
  can::SocketCan bus;
  v4l2::V4l2Output output;
};

// Sends every frame and CAN frame at its deadline since the start, until
// the end of the drive, --max-frames or a stop signal.
LiveCounters play(const LiveOptions& options, Playback& p) {
  LiveCounters counters;
  const io::Y4mFormat& format = p.video.format();
  std::vector<std::uint8_t> luma(format.luma_bytes());
  const auto frame_period_ns = static_cast<std::int64_t>(format.frame_period_s() * 1e9);
  const std::vector<can::CanFrame>& odometry = p.odometry;
  std::size_t frame = 0, next_can = 0;
  bool frame_ready = p.video.read_frame(luma) == io::Y4mRead::kFrame;
  const std::int64_t start = monotonic_ns();
  std::size_t next_report = 1;
  const std::size_t limit = options.max_frames;
  while (g_stop == 0) {
    const bool frames_left = frame_ready && (limit == 0 || frame < limit);
    const bool can_left =
        next_can < odometry.size() && (frames_left || odometry[next_can].timestamp_ns <=
                                                          static_cast<std::int64_t>(frame) * frame_period_ns);
    if (!frames_left && !can_left) break;
    const std::int64_t frame_due = static_cast<std::int64_t>(frame) * frame_period_ns;
    const bool send_frame = frames_left && (!can_left || frame_due <= odometry[next_can].timestamp_ns);
    const std::int64_t due = send_frame ? frame_due : odometry[next_can].timestamp_ns;
    if (!sleep_until(start + due)) break;
    const double late_ms = static_cast<double>(monotonic_ns() - start - due) / 1e6;
    if (late_ms > 5.0) ++counters.late_events;
    counters.max_lateness_ms = std::max(counters.max_lateness_ms, late_ms);
    if (send_frame) {
      if (p.output.send_luma(luma, std::chrono::milliseconds(50)))
        ++counters.frame_errors;
      else
        ++counters.frames_sent;
      ++frame;
      frame_ready = p.video.read_frame(luma) == io::Y4mRead::kFrame;
      if (options.progress && counters.frames_sent >= next_report * 100) {
        std::fprintf(stderr, "markloop-sim: live: %zu frames\n", frame);
        ++next_report;
      }
    } else {
      can::CanFrame out = odometry[next_can++];
      out.timestamp_ns = 0;  // the kernel stamps what goes on the bus
      if (p.bus.send(out))
        ++counters.can_errors;
      else
        ++counters.can_sent;
    }
  }
  counters.interrupted = g_stop != 0;
  return counters;
}

}  // namespace

Result<LiveCounters> run_live(const LiveOptions& options) {
  const std::filesystem::path dir(options.drive_dir);
  Playback p;
  if (!p.video.open((dir / "frames.y4m").string())) return error(p.video.error());
  if (!options.can_interface.empty()) {
    Result<std::vector<can::CanFrame>> odometry = load_odometry((dir / "odometry.log").string());
    if (!odometry) return odometry.error();
    p.odometry = std::move(odometry).value();
  }
  if (Status opened = open_bus(options, p.bus); !opened) return opened.error();
  if (Status started = start_output(options, p.video.format(), p.output); !started) return started.error();
  stop_on_signals();
  const LiveCounters counters = play(options, p);
  p.output.stop();
  p.bus.close();
  return counters;
}

}  // namespace markloop::sim
