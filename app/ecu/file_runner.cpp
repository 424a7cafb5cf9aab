// File mode: frames from a .y4m file, CAN from a candump log, both on the
// recording's time base (frame k at k / fps, log stamps from 0), merged in
// time order. As fast as possible, or paced to the recorded rate with
// --realtime (absolute deadlines; a frame found more than one period late is
// skipped and counted, like an overrun on the car).
//
// Either input may be a pipe: every wait for its data, and the pacing
// sleep, also ends on SIGTERM or SIGINT. Whatever ends the run (the end of
// the files, a signal, or an input error), the map is saved as it stood
// after the last whole frame; an input error still exits 2.
#include <poll.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>

#include <opencv2/core.hpp>

#include "app/common/result.hpp"
#include "app/ecu/runner.hpp"
#include "app/io/y4m.hpp"
#include "app/perception/marking_classes.hpp"
#include "drivers/can/candump_log.hpp"
#include "platform/files.hpp"
#include "platform/os.hpp"

namespace markloop::ecu {

namespace {

using std::chrono::nanoseconds;

class DetectionsCsv {
 public:
  ~DetectionsCsv() { (void)close(); }
  // "PATH: cannot write: why" when the file cannot be created.
  Status open(const std::string& path) {
    path_ = path;
    file_ = std::fopen(path.c_str(), "w");
    if (file_ == nullptr) {
      const int reason = errno;
      return error(path + ": cannot write: " + std::strerror(reason));
    }
    std::setvbuf(file_, buffer_.data(), _IOFBF, buffer_.size());  // no heap for stdio
    std::fputs("frame,label,score,x1,y1,x2,y2,x3,y3,x4,y4,ground_x,ground_y,turned\n", file_);
    return {};
  }
  void write(std::uint64_t frame, std::span<const perception::Detection> detections) {
    if (file_ == nullptr) return;
    for (const perception::Detection& d : detections) {
      const std::string_view name = perception::marking_class_name(d.label);
      std::fprintf(file_, "%llu,%.*s,%.3f,%.1f,%.1f,%.1f,%.1f,%.1f,%.1f,%.1f,%.1f,%.3f,%.3f,%d\n",
                   static_cast<unsigned long long>(frame), static_cast<int>(name.size()), name.data(),
                   double(d.score), double(d.quad[0][0]), double(d.quad[0][1]), double(d.quad[1][0]),
                   double(d.quad[1][1]), double(d.quad[2][0]), double(d.quad[2][1]), double(d.quad[3][0]),
                   double(d.quad[3][1]), double(d.ground_x), double(d.ground_y), d.turned ? 1 : 0);
    }
  }
  // "PATH: write error" when a write or the close failed.
  Status close() {
    if (file_ == nullptr) return {};
    const bool ok = std::ferror(file_) == 0;
    const bool closed = std::fclose(file_) == 0;
    file_ = nullptr;
    if (!(ok && closed)) return error(path_ + ": write error");
    return {};
  }

 private:
  std::string path_;
  std::FILE* file_ = nullptr;
  std::array<char, 1 << 16> buffer_{};
};

// The landmarks this run made, oldest first, for markloop-eval to judge
// against the simulator's markings; not those of a loaded map (negative
// stations), whose frames are another recording's. Once, after the recording.
// "PATH: cannot write: why" when it cannot be written.
Status write_landmarks_csv(const std::string& path, const SequenceDatabase& database) {
  std::FILE* file = std::fopen(path.c_str(), "w");
  if (file == nullptr) {
    const int reason = errno;
    return error(path + ": cannot write: " + std::strerror(reason));
  }
  std::fputs("label,observations,first_frame,last_frame,x,y,car_x,car_y,car_yaw,has_car_pose,facing\n", file);
  for (LandmarkId id = database.first_landmark_id(); id != database.next_landmark_id(); ++id) {
    const Landmark* l = database.landmark(id);
    if (l == nullptr || l->station < 0.0) continue;
    const std::string_view name = perception::marking_class_name(l->label);
    std::fprintf(file, "%.*s,%u,%u,%u,%.3f,%.3f,%.3f,%.3f,%.6f,%d,%d\n", static_cast<int>(name.size()),
                 name.data(), unsigned{l->observations}, l->first_frame, l->last_frame, double(l->x),
                 double(l->y), double(l->car_x), double(l->car_y), double(l->car_yaw),
                 l->has_car_pose ? 1 : 0, static_cast<int>(l->facing));
  }
  const bool ok = std::ferror(file) == 0;
  const bool closed = std::fclose(file) == 0;
  const int reason = errno;
  if (!(closed && ok)) return error(path + ": cannot write: " + std::strerror(reason));
  return {};
}

nanoseconds frame_time(std::uint64_t k, const io::Y4mFormat& format) {
  // Exact in integers: k * den / num seconds.
  const long double seconds = static_cast<long double>(k) * format.fps_denominator / format.fps_numerator;
  return nanoseconds(static_cast<std::int64_t>(std::llround(seconds * 1e9L)));
}

// A log stamped later than this is on the wall clock (candump -l without
// rebasing), not on the recording's time base: 10^9 s is the year 2001.
constexpr nanoseconds kLatestRecordingStamp = std::chrono::seconds(1'000'000'000);
// Status cycles run between checks for a stop request.
constexpr unsigned kCyclesPerStopCheck = 256;

std::string seconds_text(nanoseconds t) {
  char text[48];
  std::snprintf(text, sizeof text, "%.6f s", std::chrono::duration<double>(t).count());
  return text;
}

// One run over the recording. The steps are the members; run() orders them.
class FileRun {
 public:
  FileRun(const EcuConfig& config, io::Y4mReader& frames, can::CandumpLogReader& can_in, Ecu& ecu,
          int stop_fd, int pacing_timer_fd)
      : config_(config),
        frames_(frames),
        can_in_(can_in),
        ecu_(ecu),
        stop_fd_(stop_fd),
        pacing_timer_fd_(pacing_timer_fd),
        format_(frames.format()),
        status_period_(std::chrono::milliseconds(config.status_period_ms)),
        next_status_(status_period_) {}

  // 0 at the end of the files or on a stop request, 2 on an input error.
  int run(DetectionsCsv& detections_csv);
  int stop_signal() const { return stop_signal_; }

 private:
  void read_next_can();
  bool check_can_stamp(nanoseconds stamp);
  void feed_until(nanoseconds t);
  bool wait_for_deadline(std::uint64_t k, nanoseconds t);
  void count_unused_can_frames();
  bool input_error(const std::string& message);
  void poll_stop() {
    if (stop_signal_ == 0) stop_signal_ = detail::pending_stop_signal(stop_fd_);
  }

  const EcuConfig& config_;
  io::Y4mReader& frames_;
  can::CandumpLogReader& can_in_;
  Ecu& ecu_;
  int stop_fd_;
  int pacing_timer_fd_;
  io::Y4mFormat format_;
  nanoseconds status_period_;
  nanoseconds next_status_;
  can::CandumpRecord next_{};
  bool have_next_ = false;
  bool failed_ = false;
  nanoseconds last_can_stamp_{-1};
  nanoseconds pace_start_{0};
  int stop_signal_ = 0;
};

bool FileRun::input_error(const std::string& message) {
  std::fprintf(stderr, "markloop: %s\n", message.c_str());
  failed_ = true;
  return false;
}

// A log out of time order would hold every later frame back until its
// stamp; one on the wall clock would never be reached at all.
bool FileRun::check_can_stamp(nanoseconds stamp) {
  const std::string where = can_in_.path() + ":" + std::to_string(can_in_.line_number());
  if (last_can_stamp_.count() < 0 && stamp >= kLatestRecordingStamp)
    return input_error(where + ": timestamp " + seconds_text(stamp) +
                       " is a wall-clock (epoch) time; file mode needs the recording's time base, 0 at "
                       "the first camera frame (subtract the first stamp from every line)");
  if (stamp < last_can_stamp_)
    return input_error(where + ": timestamp " + seconds_text(stamp) + " is earlier than the line before's (" +
                       seconds_text(last_can_stamp_) + "): the log must be in time order");
  last_can_stamp_ = stamp;
  return true;
}

void FileRun::read_next_can() {
  have_next_ = false;
  switch (can_in_.next(next_)) {
    case can::CandumpLogReader::Status::Frame:
      have_next_ = check_can_stamp(nanoseconds(next_.frame.timestamp_ns));
      break;
    case can::CandumpLogReader::Status::End:
      break;
    case can::CandumpLogReader::Status::Stopped:
      poll_stop();
      break;
    case can::CandumpLogReader::Status::Error:
      input_error(can_in_.error());
      break;
  }
}

// CAN frames and status cycles due by `t`, in time order.
void FileRun::feed_until(nanoseconds t) {
  for (unsigned cycles = 0; !failed_ && stop_signal_ == 0;) {
    const nanoseconds can_t = have_next_ ? nanoseconds(next_.frame.timestamp_ns) : nanoseconds::max();
    if (next_status_ <= t && next_status_ <= can_t) {
      ecu_.send_status(next_status_);
      next_status_ += status_period_;
      if (++cycles % kCyclesPerStopCheck == 0) poll_stop();
    } else if (have_next_ && can_t <= t) {
      ecu_.on_can_frame(next_.frame, can_t);
      read_next_can();
    } else {
      return;
    }
  }
}

// --realtime: sleeps to frame k's absolute deadline; false on a stop request.
bool FileRun::wait_for_deadline(std::uint64_t k, nanoseconds t) {
  const nanoseconds first_time = frame_time(config_.first_frame, format_);
  if (k == config_.first_frame) pace_start_ = platform::monotonic_now();
  (void)platform::arm_timer_absolute(pacing_timer_fd_, pace_start_ + t - first_time, nanoseconds(0));
  std::uint64_t expirations = 0;
  while (expirations == 0 && stop_signal_ == 0) {
    pollfd fds[2] = {{stop_fd_, POLLIN, 0}, {pacing_timer_fd_, POLLIN, 0}};
    int ready = 0;
    (void)platform::sys_poll(fds, 2, std::chrono::milliseconds(-1), ready);
    if ((fds[0].revents & POLLIN) != 0) poll_stop();
    if ((fds[1].revents & POLLIN) != 0) (void)platform::read_timer(pacing_timer_fd_, expirations);
  }
  return stop_signal_ == 0;
}

// Frames stamped after the last camera frame cannot be used: counted and
// reported, so that a log from another drive does not pass unnoticed.
void FileRun::count_unused_can_frames() {
  std::uint64_t unused = 0;
  for (; have_next_ && stop_signal_ == 0 && !failed_; read_next_can()) ++unused;
  ecu_.count_unused_can_frames(unused);
}

int FileRun::run(DetectionsCsv& detections_csv) {
  const nanoseconds period = frame_time(1, format_);
  const nanoseconds first_time = frame_time(config_.first_frame, format_);
  cv::Mat grey(format_.height, format_.width, CV_8UC1);
  read_next_can();
  nanoseconds last_time{0};
  std::uint64_t k = 0;
  for (;; ++k) {
    const nanoseconds t = frame_time(k, format_);
    if (config_.realtime_replay && k >= config_.first_frame && !wait_for_deadline(k, t)) break;
    feed_until(t);
    if (failed_ || stop_signal_ != 0) break;
    const io::Y4mRead read = frames_.read_frame(std::span<std::uint8_t>(grey.data, grey.total()));
    if (read == io::Y4mRead::kEnd) break;
    if (read == io::Y4mRead::kStopped) {
      poll_stop();
      break;
    }
    if (read == io::Y4mRead::kError) {
      input_error(frames_.error());
      break;
    }
    last_time = t;
    if (k < config_.first_frame) continue;  // before this drive: only the odometry counts
    if (config_.frame_count > 0 && k >= config_.first_frame + config_.frame_count) break;
    const auto arrival = SteadyClock::now();
    if (config_.realtime_replay && platform::monotonic_now() - (pace_start_ + t - first_time) > period) {
      ecu_.count_dropped_frames(1);  // we are a frame behind: skip, count, keep going
      continue;
    }
    ecu_.set_next_frame(static_cast<FrameIndex>(k));
    detections_csv.write(k, ecu_.on_frame(grey, t, arrival));
    poll_stop();
  }
  if (!failed_ && stop_signal_ == 0 && config_.first_frame > 0 && k <= config_.first_frame)
    input_error(config_.camera.file + ": --first-frame (file.first_frame) is " +
                std::to_string(config_.first_frame) + ", but the file ends after " + std::to_string(k) +
                " frames");
  if (!failed_ && stop_signal_ == 0) {
    // End of the recording: the rest of the log. Tracks still in view are
    // left unfinished, as when the car stops: committing them cut short
    // would misplace them.
    feed_until(last_time);
    count_unused_can_frames();
  }
  return failed_ ? 2 : 0;
}

// Opens the inputs and outputs; the exit status when one cannot be used (2
// an input, 1 an output, as every tool), reported; 0 when all are open.
int open_files(const RunOptions& options, io::Y4mReader& frames, can::CandumpLogReader& can_in,
               can::CandumpLogWriter& can_out, DetectionsCsv& detections_csv) {
  const EcuConfig& config = options.config;
  if (!frames.open(config.camera.file, options.camera.width(), options.camera.height())) {
    std::fprintf(stderr, "markloop: %s\n", frames.error().c_str());
    return 2;
  }
  if (auto ec = can_in.open(config.can.in_log)) {
    std::fprintf(stderr, "markloop: %s\n",
                 platform::describe_read_error(config.can.in_log, ec, 0, "a candump log").c_str());
    return 2;
  }
  if (!config.can.out_log.empty()) {
    if (auto ec = can_out.open(config.can.out_log.c_str(), "vcan0")) {
      std::fprintf(stderr, "markloop: %s: cannot write: %s\n", config.can.out_log.c_str(),
                   ec.message().c_str());
      return 1;
    }
  }
  if (!config.detections_out.empty()) {
    if (const Status opened = detections_csv.open(config.detections_out); !opened) {
      std::fprintf(stderr, "markloop: %s\n", opened.message().c_str());
      return 1;
    }
  }
  return 0;
}

// Closes the outputs; false (reported) when one of them failed.
bool close_outputs(const EcuConfig& config, const Ecu& ecu, can::CandumpLogWriter& can_out,
                   DetectionsCsv& detections_csv) {
  bool ok = true;
  if (!config.landmarks_out.empty()) {
    if (const Status written = write_landmarks_csv(config.landmarks_out, ecu.engine().database()); !written) {
      std::fprintf(stderr, "markloop: %s\n", written.message().c_str());
      ok = false;
    }
  }
  if (auto ec = can_out.close()) {
    std::fprintf(stderr, "markloop: %s: %s\n", config.can.out_log.c_str(), ec.message().c_str());
    ok = false;
  }
  if (const Status closed = detections_csv.close(); !closed) {
    std::fprintf(stderr, "markloop: %s\n", closed.message().c_str());
    ok = false;
  }
  return ok;
}

}  // namespace

int run_file_mode(const RunOptions& options) {
  EcuConfig config = options.config;
  io::Y4mReader frames;
  can::CandumpLogReader can_in;
  can::CandumpLogWriter can_out;
  DetectionsCsv detections_csv;
  if (const int status = open_files(options, frames, can_in, can_out, detections_csv); status != 0)
    return status;
  const io::Y4mFormat format = frames.format();
  config.camera.fps =
      static_cast<unsigned>(std::max(1L, std::lround(double(format.fps_numerator) / format.fps_denominator)));

  Ecu ecu(config, options.camera, options.detector, nullptr, can_out.is_open() ? &can_out : nullptr);
  const platform::UniqueFd signals = detail::open_stop_signals();
  frames.set_stop_fd(signals.get());
  can_in.set_stop_fd(signals.get());
  platform::UniqueFd pacing_timer;
  if (config.realtime_replay) {
    if (auto ec = platform::open_timerfd(pacing_timer)) {
      std::fprintf(stderr, "markloop: timerfd: %s\n", ec.message().c_str());
      return 2;
    }
  }
  if (!detail::start_up(ecu, config, options.quiet)) return 2;
  // Ready as on the car: SIGTERM and SIGINT from now on save the map.
  platform::SystemdNotifier systemd = detail::open_systemd_notifier();
  (void)systemd.notify("READY=1");

  const nanoseconds wall_start = platform::monotonic_now();
  FileRun run(config, frames, can_in, ecu, signals.get(), pacing_timer.get());
  int exit_status = run.run(detections_csv);
  if (run.stop_signal() != 0 && !options.quiet)
    std::fprintf(stderr, "markloop: %s: stopping\n", strsignal(run.stop_signal()));
  // What was learnt up to an input error is kept: the engine stands at a frame boundary.
  const bool saved = detail::shut_down(ecu, config, options.quiet);
  const bool closed = close_outputs(config, ecu, can_out, detections_csv);
  const double wall = std::chrono::duration<double>(platform::monotonic_now() - wall_start).count();
  const bool reported =
      detail::report(ecu, options, wall, config.realtime_replay ? "file (realtime)" : "file");
  if (exit_status == 0 && !(saved && closed && reported)) exit_status = 1;
  return exit_status;
}

}  // namespace markloop::ecu
