// Live mode: V4L2 camera and SocketCAN in one poll() loop with a timerfd for
// the Status cycle (absolute deadlines; missed ones are counted as overruns)
// and a signalfd for SIGTERM/SIGINT. Devices that fail are retried with
// back-off by their drivers (and by this loop when they never opened); the
// ECU keeps running degraded meanwhile and says so in Status.
#include <poll.h>
#include <time.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstring>

#include <opencv2/core.hpp>

#include "app/ecu/runner.hpp"
#include "dbc/markloop_messages.hpp"
#include "drivers/can/candump_log.hpp"
#include "drivers/can/socketcan.hpp"
#include "drivers/v4l2/v4l2_camera.hpp"
#include "platform/os.hpp"

namespace markloop::ecu {

namespace {

using std::chrono::milliseconds;
using std::chrono::nanoseconds;

constexpr std::size_t kMaxCanFramesPerWakeup = 64;  // a flood cannot starve the camera
constexpr milliseconds kReopenInterval{1000};       // devices that never opened

nanoseconds realtime_now() {
  timespec ts{};
  ::clock_gettime(CLOCK_REALTIME, &ts);
  return std::chrono::seconds(ts.tv_sec) + nanoseconds(ts.tv_nsec);
}

// The luma of a frame as a CV_8UC1 image of the camera's size: a header over
// the driver's buffer for GREY, a copy of every other byte for YUYV.
bool luma_of(const v4l2::FrameView& view, cv::Mat& yuyv_luma, cv::Mat& out) {
  if (view.data == nullptr || std::uint64_t{view.stride} * view.height > view.bytes_used) return false;
  if (view.format == v4l2::PixelFormat::Grey) {
    if (view.stride < view.width) return false;
    out = cv::Mat(static_cast<int>(view.height), static_cast<int>(view.width), CV_8UC1,
                  const_cast<std::uint8_t*>(view.data), view.stride);
    return true;
  }
  if (view.stride < 2 * view.width || yuyv_luma.cols != static_cast<int>(view.width) ||
      yuyv_luma.rows != static_cast<int>(view.height))
    return false;
  for (std::uint32_t row = 0; row < view.height; ++row) {
    const std::uint8_t* in = view.data + std::size_t{row} * view.stride;
    std::uint8_t* luma = yuyv_luma.ptr<std::uint8_t>(static_cast<int>(row));
    for (std::uint32_t col = 0; col < view.width; ++col) luma[col] = in[2 * col];
  }
  out = yuyv_luma;
  return true;
}

}  // namespace

int run_live_mode(const RunOptions& options) {
  const EcuConfig& config = options.config;
  const bool quiet = options.quiet;

  v4l2::CameraConfig camera_config;
  camera_config.device = config.camera.device;
  camera_config.input = config.camera.input;
  camera_config.width = static_cast<std::uint32_t>(options.camera.width());
  camera_config.height = static_cast<std::uint32_t>(options.camera.height());
  camera_config.format =
      config.camera.format == PixelFormat::kGrey ? v4l2::PixelFormat::Grey : v4l2::PixelFormat::Yuyv;
  camera_config.fps = config.camera.fps;
  camera_config.frame_timeout = milliseconds(config.camera.timeout_ms);
  if (auto ec = v4l2::V4l2Camera::validate(camera_config)) {
    std::fprintf(stderr, "markloop: camera configuration: %s\n", ec.message().c_str());
    return 2;
  }
  can::CandumpLogWriter can_log;
  if (!config.can.out_log.empty()) {
    if (auto ec = can_log.open(config.can.out_log.c_str(), config.can.interface)) {
      std::fprintf(stderr, "markloop: %s: cannot write: %s\n", config.can.out_log.c_str(),
                   ec.message().c_str());
      return 1;
    }
  }

  v4l2::V4l2Camera camera;
  can::SocketCan can_bus;
  Ecu ecu(config, options.camera, options.detector, &can_bus, can_log.is_open() ? &can_log : nullptr);
  cv::Mat yuyv_luma(options.camera.height(), options.camera.width(), CV_8UC1);
  cv::Mat grey;
  const platform::UniqueFd signals = detail::open_stop_signals();
  platform::UniqueFd status_timer;
  if (auto ec = platform::open_timerfd(status_timer)) {
    std::fprintf(stderr, "markloop: timerfd: %s\n", ec.message().c_str());
    return 2;
  }
  platform::SystemdNotifier systemd = detail::open_systemd_notifier();
  if (!detail::start_up(ecu, config, quiet)) return 2;

  const std::array<can::CanFilter, 2> filters = {can::CanFilter::exact(dbc::VehicleOdometry::kId),
                                                 can::CanFilter::exact(dbc::Command::kId)};
  const nanoseconds start = platform::monotonic_now();
  ecu.set_stamp_offset(realtime_now() - start);
  nanoseconds next_camera_attempt = start, next_can_attempt = start;
  const auto try_open_devices = [&](nanoseconds now) {
    if (camera.state() == v4l2::V4l2Camera::State::Closed && now >= next_camera_attempt) {
      if (auto ec = camera.start(camera_config)) {
        next_camera_attempt = now + kReopenInterval;
        if (!quiet)
          std::fprintf(stderr, "markloop: camera %s: %s (retrying)\n", config.camera.device.c_str(),
                       ec.message().c_str());
      }
    }
    if (can_bus.state() == can::SocketCan::State::Closed && now >= next_can_attempt) {
      if (auto ec = can_bus.open(config.can.interface, filters)) {
        next_can_attempt = now + kReopenInterval;
        if (!quiet)
          std::fprintf(stderr, "markloop: CAN %s: %s (retrying)\n", config.can.interface.c_str(),
                       ec.message().c_str());
      }
    }
  };
  try_open_devices(start);

  const nanoseconds status_period = milliseconds(config.status_period_ms);
  (void)platform::arm_timer_absolute(status_timer.get(), start + status_period, status_period);
  (void)systemd.notify("READY=1");
  nanoseconds last_watchdog = start;
  const nanoseconds frame_period(1'000'000'000LL / (config.camera.fps == 0 ? 10U : config.camera.fps));
  std::uint64_t camera_dropped_seen = 0;
  const nanoseconds min_frame_spacing =
      config.camera.max_rate == 0 ? nanoseconds(0)
                                  : nanoseconds(1'000'000'000LL / config.camera.max_rate) - milliseconds(2);
  nanoseconds last_processed = nanoseconds::min() / 2;
  int stop_signal = 0;

  while (stop_signal == 0) {
    std::array<pollfd, 4> fds{};
    fds[0] = {signals.get(), POLLIN, 0};
    fds[1] = {status_timer.get(), POLLIN, 0};
    fds[2] = {camera.device().fd(), POLLIN, 0};  // -1 (ignored by poll) while recovering
    fds[3] = {can_bus.fd(), static_cast<short>(POLLIN | (can_bus.tx_pending() > 0 ? POLLOUT : 0)), 0};
    // Devices that are recovering are serviced at least every 20 ms.
    const bool camera_healthy = camera.state() == v4l2::V4l2Camera::State::Streaming;
    const bool can_healthy = can_bus.state() == can::SocketCan::State::Open;
    const milliseconds timeout = camera_healthy && can_healthy ? milliseconds(-1) : milliseconds(20);
    int ready = 0;
    (void)platform::sys_poll(fds.data(), static_cast<unsigned>(fds.size()), timeout, ready);
    const nanoseconds now = platform::monotonic_now();

    if ((fds[0].revents & POLLIN) != 0) stop_signal = detail::pending_stop_signal(signals.get());

    if ((fds[3].revents & (POLLIN | POLLERR)) != 0) {
      can::CanFrame frame;
      for (std::size_t i = 0; i < kMaxCanFramesPerWakeup && !can_bus.receive(frame); ++i)
        ecu.on_can_frame(frame, platform::monotonic_now() - start);
    }
    can_bus.service();

    if (camera.state() != v4l2::V4l2Camera::State::Closed &&
        ((fds[2].revents & (POLLIN | POLLERR | POLLHUP)) != 0 || !camera_healthy)) {
      v4l2::FrameView view;
      if (!camera.wait_frame(view, milliseconds(0))) {
        const nanoseconds captured = view.timestamp_monotonic && view.timestamp_ns > 0
                                         ? nanoseconds(view.timestamp_ns)
                                         : platform::monotonic_now();
        const auto arrival = SteadyClock::now();
        if (captured - last_processed < min_frame_spacing) {
          ecu.count_frame_over_rate();
        } else if (platform::monotonic_now() - captured > frame_period) {
          ecu.count_dropped_frames(1);  // already a period old: skip, count, keep going
        } else if (luma_of(view, yuyv_luma, grey)) {
          last_processed = captured;
          (void)ecu.on_frame(grey, captured - start, arrival);
        } else {
          ecu.count_dropped_frames(1);
        }
        (void)camera.release(view);
      }
      const std::uint64_t dropped = camera.counters().dropped;
      if (dropped > camera_dropped_seen) ecu.count_dropped_frames(dropped - camera_dropped_seen);
      camera_dropped_seen = dropped;
    }
    try_open_devices(now);

    if ((fds[1].revents & POLLIN) != 0) {
      std::uint64_t expirations = 0;
      (void)platform::read_timer(status_timer.get(), expirations);
      if (expirations > 1) ecu.count_overruns(expirations - 1);
      ecu.set_camera_lost(camera.state() != v4l2::V4l2Camera::State::Streaming);
      ecu.set_bus_fault(can_bus.state() != can::SocketCan::State::Open);
      ecu.send_status(now - start);
      if (systemd.watchdog_interval().count() > 0 && now - last_watchdog >= systemd.watchdog_interval()) {
        (void)systemd.notify("WATCHDOG=1");
        last_watchdog = now;
      }
    }
  }
  (void)systemd.notify("STOPPING=1");
  if (!quiet) std::fprintf(stderr, "markloop: %s: stopping\n", strsignal(stop_signal));
  const bool saved = detail::shut_down(ecu, config, quiet);
  camera.stop();
  can_bus.flush_tx();
  can_bus.close();
  bool closed = true;
  if (auto ec = can_log.close()) {
    std::fprintf(stderr, "markloop: %s: %s\n", config.can.out_log.c_str(), ec.message().c_str());
    closed = false;
  }
  const bool reported = detail::report(
      ecu, options, std::chrono::duration<double>(platform::monotonic_now() - start).count(), "live");
  return saved && closed && reported ? 0 : 1;
}

}  // namespace markloop::ecu
