// File mode: frames from a .y4m file, CAN from a candump log, both on the
// recording's time base (frame k at k / fps, log stamps from 0), merged in
// time order. As fast as possible, or paced to the recorded rate with
// --realtime (absolute deadlines; a frame found more than one period late is
// skipped and counted, like an overrun on the car).
#include <poll.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include <opencv2/core.hpp>

#include "drivers/can/candump_log.hpp"
#include "ecu/runner.hpp"
#include "io/y4m.hpp"
#include "perception/marking_classes.hpp"
#include "platform/os.hpp"

namespace markloop::ecu {

namespace {

using std::chrono::nanoseconds;

class DetectionsCsv {
 public:
  ~DetectionsCsv() { close(); }
  bool open(const std::string& path) {
    file_ = std::fopen(path.c_str(), "w");
    if (file_ == nullptr) return false;
    std::setvbuf(file_, buffer_.data(), _IOFBF, buffer_.size());  // no heap for stdio
    std::fputs("frame,label,score,x1,y1,x2,y2,x3,y3,x4,y4,ground_x,ground_y\n", file_);
    return true;
  }
  void write(std::uint64_t frame, std::span<const perception::Detection> detections) {
    if (file_ == nullptr) return;
    for (const perception::Detection& d : detections) {
      const std::string_view name = perception::marking_class_name(d.label);
      std::fprintf(file_, "%llu,%.*s,%.3f,%.1f,%.1f,%.1f,%.1f,%.1f,%.1f,%.1f,%.1f,%.3f,%.3f\n",
                   static_cast<unsigned long long>(frame), static_cast<int>(name.size()), name.data(),
                   double(d.score), double(d.quad[0][0]), double(d.quad[0][1]), double(d.quad[1][0]),
                   double(d.quad[1][1]), double(d.quad[2][0]), double(d.quad[2][1]),
                   double(d.quad[3][0]), double(d.quad[3][1]), double(d.ground_x), double(d.ground_y));
    }
  }
  bool close() {
    if (file_ == nullptr) return true;
    const bool ok = std::ferror(file_) == 0;
    const bool closed = std::fclose(file_) == 0;
    file_ = nullptr;
    return ok && closed;
  }

 private:
  std::FILE* file_ = nullptr;
  std::array<char, 1 << 16> buffer_{};
};

// The landmarks this run made, oldest first, for markloop-eval to judge
// against the simulator's markings; not those of a loaded map (negative
// stations), whose frames are another recording's. Once, after the recording.
bool write_landmarks_csv(const std::string& path, const SequenceDatabase& database) {
  std::FILE* file = std::fopen(path.c_str(), "w");
  if (file == nullptr) return false;
  std::fputs("label,observations,first_frame,last_frame,x,y,car_x,car_y,car_yaw,has_car_pose\n", file);
  for (LandmarkId id = database.first_landmark_id(); id != database.next_landmark_id(); ++id) {
    const Landmark* l = database.landmark(id);
    if (l == nullptr || l->station < 0.0) continue;
    const std::string_view name = perception::marking_class_name(l->label);
    std::fprintf(file, "%.*s,%u,%u,%u,%.3f,%.3f,%.3f,%.3f,%.6f,%d\n", static_cast<int>(name.size()), name.data(),
                 unsigned{l->observations}, l->first_frame, l->last_frame, double(l->x), double(l->y),
                 double(l->car_x), double(l->car_y), double(l->car_yaw), l->has_car_pose ? 1 : 0);
  }
  const bool ok = std::ferror(file) == 0;
  return std::fclose(file) == 0 && ok;
}

nanoseconds frame_time(std::uint64_t k, const io::Y4mFormat& format) {
  // Exact in integers: k * den / num seconds.
  const long double seconds =
      static_cast<long double>(k) * format.fps_denominator / format.fps_numerator;
  return nanoseconds(static_cast<std::int64_t>(std::llround(seconds * 1e9L)));
}

}  // namespace

int run_file_mode(const RunOptions& options) {
  EcuConfig config = options.config;
  const bool quiet = options.quiet;
  io::Y4mReader frames;
  if (!frames.open(config.camera.file, options.camera.width(), options.camera.height())) {
    std::fprintf(stderr, "markloop: %s\n", frames.error().c_str());
    return 2;
  }
  const io::Y4mFormat format = frames.format();
  if (format.fps_numerator <= 0 || format.fps_denominator <= 0) {
    std::fprintf(stderr, "markloop: %s: frame rate %d:%d is not usable\n", config.camera.file.c_str(),
                 format.fps_numerator, format.fps_denominator);
    return 2;
  }
  config.camera.fps = static_cast<unsigned>(
      std::max(1L, std::lround(double(format.fps_numerator) / format.fps_denominator)));
  const nanoseconds period = frame_time(1, format);

  can::CandumpLogReader can_in;
  if (auto ec = can_in.open(config.can.in_log)) {
    std::fprintf(stderr, "markloop: %s: cannot open: %s\n", config.can.in_log.c_str(), ec.message().c_str());
    return 2;
  }
  can::CandumpLogWriter can_out;
  if (!config.can.out_log.empty()) {
    if (auto ec = can_out.open(config.can.out_log.c_str(), "vcan0")) {
      std::fprintf(stderr, "markloop: %s: cannot write: %s\n", config.can.out_log.c_str(),
                   ec.message().c_str());
      return 2;
    }
  }
  DetectionsCsv detections_csv;
  if (!config.detections_out.empty() && !detections_csv.open(config.detections_out)) {
    std::fprintf(stderr, "markloop: %s: cannot write: %s\n", config.detections_out.c_str(),
                 std::strerror(errno));
    return 2;
  }

  Ecu ecu(config, options.camera, options.detector, nullptr, can_out.is_open() ? &can_out : nullptr);
  const platform::UniqueFd signals = detail::open_stop_signals();
  platform::UniqueFd pacing_timer;
  if (config.realtime_replay) {
    if (auto ec = platform::open_timerfd(pacing_timer)) {
      std::fprintf(stderr, "markloop: timerfd: %s\n", ec.message().c_str());
      return 2;
    }
  }
  cv::Mat grey(format.height, format.width, CV_8UC1);
  detail::start_up(ecu, config, quiet);
  // Ready as on the car: SIGTERM and SIGINT from now on save the map.
  platform::SystemdNotifier systemd = detail::open_systemd_notifier();
  (void)systemd.notify("READY=1");

  can::CandumpRecord next{};
  bool have_next = false;
  bool input_error = false;
  const auto read_next = [&] {
    have_next = false;
    switch (can_in.next(next)) {
      case can::CandumpLogReader::Status::Frame: have_next = true; break;
      case can::CandumpLogReader::Status::End: break;
      case can::CandumpLogReader::Status::Error:
        std::fprintf(stderr, "markloop: %s\n", can_in.error().c_str());
        input_error = true;
        break;
    }
  };
  read_next();
  const nanoseconds status_period = std::chrono::milliseconds(config.status_period_ms);
  nanoseconds next_status = status_period;
  // CAN frames and status cycles due by `t`, in time order.
  const auto feed_until = [&](nanoseconds t) {
    for (;;) {
      const nanoseconds can_t = have_next ? nanoseconds(next.frame.timestamp_ns)
                                          : nanoseconds::max();
      if (next_status <= t && next_status <= can_t) {
        ecu.send_status(next_status);
        next_status += status_period;
      } else if (have_next && can_t <= t) {
        ecu.on_can_frame(next.frame, can_t);
        read_next();
      } else {
        return;
      }
    }
  };

  const nanoseconds wall_start = platform::monotonic_now();
  // --realtime paces from the first processed frame.
  const nanoseconds first_time = frame_time(config.first_frame, format);
  nanoseconds pace_start = wall_start;  // reset at the first processed frame
  int stop_signal = 0;
  int exit_status = 0;
  nanoseconds last_time{0};
  for (std::uint64_t k = 0;; ++k) {
    const nanoseconds t = frame_time(k, format);
    if (config.realtime_replay && k >= config.first_frame) {
      if (k == config.first_frame) pace_start = platform::monotonic_now();
      // Sleep to the frame's absolute deadline; a signal ends the wait.
      (void)platform::arm_timer_absolute(pacing_timer.get(), pace_start + t - first_time, nanoseconds(0));
      std::uint64_t expirations = 0;
      while (expirations == 0 && stop_signal == 0) {
        pollfd fds[2] = {{signals.get(), POLLIN, 0}, {pacing_timer.get(), POLLIN, 0}};
        int ready = 0;
        (void)platform::sys_poll(fds, 2, std::chrono::milliseconds(-1), ready);
        if ((fds[0].revents & POLLIN) != 0) stop_signal = detail::pending_stop_signal(signals.get());
        if ((fds[1].revents & POLLIN) != 0) (void)platform::read_timer(pacing_timer.get(), expirations);
      }
      if (stop_signal != 0) break;
    }
    feed_until(t);
    if (input_error) break;
    const io::Y4mRead read = frames.read_frame(std::span<std::uint8_t>(grey.data, grey.total()));
    if (read == io::Y4mRead::kEnd) break;
    if (read == io::Y4mRead::kError) {
      std::fprintf(stderr, "markloop: %s\n", frames.error().c_str());
      exit_status = 2;
      break;
    }
    last_time = t;
    if (k < config.first_frame) continue;  // before this drive: only the odometry counts
    if (config.frame_count > 0 && k >= config.first_frame + config.frame_count) break;
    const auto arrival = SteadyClock::now();
    if (config.realtime_replay && platform::monotonic_now() - (pace_start + t - first_time) > period) {
      ecu.count_dropped_frames(1);  // we are a frame behind: skip, count, keep going
      continue;
    }
    ecu.set_next_frame(static_cast<FrameIndex>(k));
    detections_csv.write(k, ecu.on_frame(grey, t, arrival));
    if ((stop_signal = detail::pending_stop_signal(signals.get())) != 0) break;
  }
  if (input_error) exit_status = 2;
  if (exit_status == 0 && stop_signal == 0) {
    // End of the recording: the rest of the log. Tracks still in view are
    // left unfinished, as when the car stops: committing them cut short
    // would misplace them.
    feed_until(last_time);
  }
  if (stop_signal != 0 && !quiet)
    std::fprintf(stderr, "markloop: %s: stopping\n", strsignal(stop_signal));
  if (exit_status == 0) detail::shut_down(ecu, config, quiet);
  if (!config.landmarks_out.empty() && !write_landmarks_csv(config.landmarks_out, ecu.engine().database())) {
    std::fprintf(stderr, "markloop: %s: cannot write: %s\n", config.landmarks_out.c_str(), std::strerror(errno));
    exit_status = exit_status == 0 ? 1 : exit_status;
  }
  if (auto ec = can_out.close()) {
    std::fprintf(stderr, "markloop: %s: %s\n", config.can.out_log.c_str(), ec.message().c_str());
    exit_status = exit_status == 0 ? 1 : exit_status;
  }
  if (!detections_csv.close()) {
    std::fprintf(stderr, "markloop: %s: write error\n", config.detections_out.c_str());
    exit_status = exit_status == 0 ? 1 : exit_status;
  }
  const double wall = std::chrono::duration<double>(platform::monotonic_now() - wall_start).count();
  detail::report(ecu, options, wall, config.realtime_replay ? "file (realtime)" : "file");
  return exit_status;
}

}  // namespace markloop::ecu
