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

v4l2::CameraConfig camera_config_for(const RunOptions& options) {
  const EcuConfig& config = options.config;
  v4l2::CameraConfig camera_config;
  camera_config.device = config.camera.device;
  camera_config.input = config.camera.input;
  camera_config.width = static_cast<std::uint32_t>(options.camera.width());
  camera_config.height = static_cast<std::uint32_t>(options.camera.height());
  camera_config.format =
      config.camera.format == PixelFormat::kGrey ? v4l2::PixelFormat::Grey : v4l2::PixelFormat::Yuyv;
  camera_config.fps = config.camera.fps;
  camera_config.frame_timeout = milliseconds(config.camera.timeout_ms);
  return camera_config;
}

// The devices, the ECU and the loop's state, so that each part of a wakeup
// is a step of its own.
class LiveLoop {
 public:
  LiveLoop(const RunOptions& options, const v4l2::CameraConfig& camera_config, can::CandumpLogWriter& can_log)
      : options_(options),
        config_(options.config),
        quiet_(options.quiet),
        camera_config_(camera_config),
        can_log_(can_log),
        ecu_(config_, options.camera, options.detector, &can_bus_, can_log.is_open() ? &can_log : nullptr),
        yuyv_luma_(options.camera.height(), options.camera.width(), CV_8UC1),
        signals_(detail::open_stop_signals()),
        frame_period_(1'000'000'000LL / (config_.camera.fps == 0 ? 10U : config_.camera.fps)),
        min_frame_spacing_(config_.camera.max_rate == 0
                               ? nanoseconds(0)
                               : nanoseconds(1'000'000'000LL / config_.camera.max_rate) - milliseconds(2)) {}

  // Timer, systemd, map and devices; the exit status when the ECU must not
  // start, else 0.
  int start();
  // Until SIGTERM or SIGINT.
  void run();
  // Saves the map, closes everything and reports; the exit status.
  int stop();

 private:
  void try_open_devices(nanoseconds now);
  void receive_can();
  void service_camera(const pollfd& camera_fd, bool camera_healthy);
  void process_frame(const v4l2::FrameView& view);
  void on_status_tick(nanoseconds now);

  const RunOptions& options_;
  const EcuConfig& config_;
  const bool quiet_;
  const v4l2::CameraConfig camera_config_;
  can::CandumpLogWriter& can_log_;
  v4l2::V4l2Camera camera_;
  can::SocketCan can_bus_;
  Ecu ecu_;
  cv::Mat yuyv_luma_;
  cv::Mat grey_;
  const platform::UniqueFd signals_;
  platform::UniqueFd status_timer_;
  platform::SystemdNotifier systemd_;
  const std::array<can::CanFilter, 2> filters_ = {can::CanFilter::exact(dbc::VehicleOdometry::kId),
                                                  can::CanFilter::exact(dbc::Command::kId)};
  nanoseconds start_{0};
  nanoseconds next_camera_attempt_{0}, next_can_attempt_{0};
  nanoseconds last_watchdog_{0};
  const nanoseconds frame_period_;
  std::uint64_t camera_dropped_seen_ = 0;
  const nanoseconds min_frame_spacing_;
  nanoseconds last_processed_ = nanoseconds::min() / 2;
  int stop_signal_ = 0;
};

int LiveLoop::start() {
  if (auto ec = platform::open_timerfd(status_timer_)) {
    std::fprintf(stderr, "markloop: timerfd: %s\n", ec.message().c_str());
    return 2;
  }
  systemd_ = detail::open_systemd_notifier();
  if (!detail::start_up(ecu_, config_, quiet_)) return 2;

  start_ = platform::monotonic_now();
  ecu_.set_stamp_offset(realtime_now() - start_);
  next_camera_attempt_ = start_;
  next_can_attempt_ = start_;
  try_open_devices(start_);

  const nanoseconds status_period = milliseconds(config_.status_period_ms);
  (void)platform::arm_timer_absolute(status_timer_.get(), start_ + status_period, status_period);
  (void)systemd_.notify("READY=1");
  last_watchdog_ = start_;
  return 0;
}

void LiveLoop::try_open_devices(nanoseconds now) {
  if (camera_.state() == v4l2::V4l2Camera::State::Closed && now >= next_camera_attempt_) {
    if (auto ec = camera_.start(camera_config_)) {
      next_camera_attempt_ = now + kReopenInterval;
      if (!quiet_)
        std::fprintf(stderr, "markloop: camera %s: %s (retrying)\n", config_.camera.device.c_str(),
                     ec.message().c_str());
    }
  }
  if (can_bus_.state() == can::SocketCan::State::Closed && now >= next_can_attempt_) {
    if (auto ec = can_bus_.open(config_.can.interface, filters_)) {
      next_can_attempt_ = now + kReopenInterval;
      if (!quiet_)
        std::fprintf(stderr, "markloop: CAN %s: %s (retrying)\n", config_.can.interface.c_str(),
                     ec.message().c_str());
    }
  }
}

void LiveLoop::run() {
  while (stop_signal_ == 0) {
    std::array<pollfd, 4> fds{};
    fds[0] = {signals_.get(), POLLIN, 0};
    fds[1] = {status_timer_.get(), POLLIN, 0};
    fds[2] = {camera_.device().fd(), POLLIN, 0};  // -1 (ignored by poll) while recovering
    fds[3] = {can_bus_.fd(), static_cast<short>(POLLIN | (can_bus_.tx_pending() > 0 ? POLLOUT : 0)), 0};
    // Devices that are recovering are serviced at least every 20 ms.
    const bool camera_healthy = camera_.state() == v4l2::V4l2Camera::State::Streaming;
    const bool can_healthy = can_bus_.state() == can::SocketCan::State::Open;
    const milliseconds timeout = camera_healthy && can_healthy ? milliseconds(-1) : milliseconds(20);
    int ready = 0;
    (void)platform::sys_poll(fds.data(), static_cast<unsigned>(fds.size()), timeout, ready);
    const nanoseconds now = platform::monotonic_now();

    if ((fds[0].revents & POLLIN) != 0) stop_signal_ = detail::pending_stop_signal(signals_.get());
    if ((fds[3].revents & (POLLIN | POLLERR)) != 0) receive_can();
    can_bus_.service();
    service_camera(fds[2], camera_healthy);
    try_open_devices(now);
    if ((fds[1].revents & POLLIN) != 0) on_status_tick(now);
  }
}

void LiveLoop::receive_can() {
  can::CanFrame frame;
  for (std::size_t i = 0; i < kMaxCanFramesPerWakeup && !can_bus_.receive(frame); ++i)
    ecu_.on_can_frame(frame, platform::monotonic_now() - start_);
}

void LiveLoop::service_camera(const pollfd& camera_fd, bool camera_healthy) {
  if (camera_.state() == v4l2::V4l2Camera::State::Closed ||
      ((camera_fd.revents & (POLLIN | POLLERR | POLLHUP)) == 0 && camera_healthy))
    return;
  v4l2::FrameView view;
  if (!camera_.wait_frame(view, milliseconds(0))) {
    process_frame(view);
    (void)camera_.release(view);
  }
  const std::uint64_t dropped = camera_.counters().dropped;
  if (dropped > camera_dropped_seen_) ecu_.count_dropped_frames(dropped - camera_dropped_seen_);
  camera_dropped_seen_ = dropped;
}

void LiveLoop::process_frame(const v4l2::FrameView& view) {
  const nanoseconds captured = view.timestamp_monotonic && view.timestamp_ns > 0
                                   ? nanoseconds(view.timestamp_ns)
                                   : platform::monotonic_now();
  const auto arrival = SteadyClock::now();
  if (captured - last_processed_ < min_frame_spacing_) {
    ecu_.count_frame_over_rate();
  } else if (platform::monotonic_now() - captured > frame_period_) {
    ecu_.count_dropped_frames(1);  // already a period old: skip, count, keep going
  } else if (luma_of(view, yuyv_luma_, grey_)) {
    last_processed_ = captured;
    (void)ecu_.on_frame(grey_, captured - start_, arrival);
  } else {
    ecu_.count_dropped_frames(1);
  }
}

void LiveLoop::on_status_tick(nanoseconds now) {
  std::uint64_t expirations = 0;
  (void)platform::read_timer(status_timer_.get(), expirations);
  if (expirations > 1) ecu_.count_overruns(expirations - 1);
  ecu_.set_camera_lost(camera_.state() != v4l2::V4l2Camera::State::Streaming);
  ecu_.set_bus_fault(can_bus_.state() != can::SocketCan::State::Open);
  ecu_.send_status(now - start_);
  if (systemd_.watchdog_interval().count() > 0 && now - last_watchdog_ >= systemd_.watchdog_interval()) {
    (void)systemd_.notify("WATCHDOG=1");
    last_watchdog_ = now;
  }
}

int LiveLoop::stop() {
  (void)systemd_.notify("STOPPING=1");
  if (!quiet_) std::fprintf(stderr, "markloop: %s: stopping\n", strsignal(stop_signal_));
  const bool saved = detail::shut_down(ecu_, config_, quiet_);
  camera_.stop();
  can_bus_.flush_tx();
  can_bus_.close();
  bool closed = true;
  if (auto ec = can_log_.close()) {
    std::fprintf(stderr, "markloop: %s: %s\n", config_.can.out_log.c_str(), ec.message().c_str());
    closed = false;
  }
  const bool reported = detail::report(
      ecu_, options_, std::chrono::duration<double>(platform::monotonic_now() - start_).count(), "live");
  return saved && closed && reported ? 0 : 1;
}

}  // namespace

int run_live_mode(const RunOptions& options) {
  const EcuConfig& config = options.config;
  const v4l2::CameraConfig camera_config = camera_config_for(options);
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
  LiveLoop loop(options, camera_config, can_log);
  if (const int status = loop.start(); status != 0) return status;
  loop.run();
  return loop.stop();
}

}  // namespace markloop::ecu
