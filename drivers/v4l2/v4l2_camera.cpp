#include "drivers/v4l2/v4l2_camera.hpp"

#include <poll.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <optional>

#include "platform/syscall.hpp"

namespace markloop::v4l2 {

namespace {

using std::chrono::duration_cast;
using std::chrono::milliseconds;
using std::chrono::nanoseconds;

constexpr std::uint32_t kMaxDimension = 16384;
constexpr std::uint32_t kMaxFps = 1000;

// Errors after which the open file is useless: the device went away or the
// queue is in an error state that only STREAMOFF/close clears.
bool is_fatal(const std::error_code& ec) noexcept {
  if (ec.category() != std::system_category()) return false;
  switch (ec.value()) {
    case ENODEV:
    case ENXIO:
    case EIO:
    case EPIPE:
    case EBADF:
      return true;
    default:
      return false;
  }
}

bool is_device_gone(const std::error_code& ec) noexcept {
  return ec.category() == std::system_category() && (ec.value() == ENODEV || ec.value() == ENXIO);
}

// Milliseconds from now until `t`, rounded up so that a wake-up is never early.
int ms_until(V4l2Camera::Clock::time_point t, V4l2Camera::Clock::time_point now) noexcept {
  if (t <= now) return 0;
  const auto ns = duration_cast<nanoseconds>(t - now).count();
  const auto ms = (ns + 999'999) / 1'000'000;
  return ms > 60'000 ? 60'000 : static_cast<int>(ms);
}

}  // namespace

const char* to_string(V4l2Camera::State state) noexcept {
  switch (state) {
    case V4l2Camera::State::Closed:
      return "Closed";
    case V4l2Camera::State::Opened:
      return "Opened";
    case V4l2Camera::State::Streaming:
      return "Streaming";
    case V4l2Camera::State::Stalled:
      return "Stalled";
    case V4l2Camera::State::Recovering:
      return "Recovering";
  }
  return "?";
}

std::error_code V4l2Camera::validate(const CameraConfig& c) noexcept {
  const bool ok = !c.device.empty() && c.device.size() < kMaxPath &&
                  c.device.find('\0') == std::string_view::npos && c.input >= -1 && c.width > 0 &&
                  c.width <= kMaxDimension && c.height > 0 && c.height <= kMaxDimension &&
                  (c.format != PixelFormat::Yuyv || c.width % 2 == 0) && c.fps <= kMaxFps &&
                  c.buffer_count >= 1 && c.buffer_count <= V4l2Device::kMaxBuffers &&
                  c.frame_timeout.count() > 0 && c.stall_restart.count() >= 0 && c.backoff_min.count() > 0 &&
                  c.backoff_max >= c.backoff_min && c.max_consecutive_errors >= 1;
  return ok ? std::error_code{} : std::make_error_code(std::errc::invalid_argument);
}

std::error_code V4l2Camera::open(const CameraConfig& config) noexcept {
  stop();
  if (auto ec = validate(config)) return ec;
  path_.fill('\0');
  std::memcpy(path_.data(), config.device.data(), config.device.size());
  config_ = config;
  config_.device = std::string_view(path_.data(), config.device.size());
  if (auto ec = open_stored()) {
    last_error_ = ec;
    return ec;
  }
  state_ = State::Opened;
  return {};
}

std::error_code V4l2Camera::start(const CameraConfig& config) noexcept {
  if (auto ec = open(config)) return ec;
  return start();
}

std::error_code V4l2Camera::start() noexcept {
  if (state_ == State::Streaming || state_ == State::Stalled || state_ == State::Recovering) return {};
  if (state_ != State::Opened) return V4l2Error::NotStreaming;
  if (auto ec = start_stream()) {
    last_error_ = ec;
    stop();
    return ec;
  }
  return {};
}

void V4l2Camera::stop() noexcept {
  device_.close();
  held_.fill(false);
  held_count_ = 0;
  ++generation_;
  state_ = State::Closed;
}

std::error_code V4l2Camera::open_stored() noexcept {
  std::error_code ec = device_.open(path_.data(), V4l2Device::Direction::Capture, info_);
  if (!ec && config_.input >= 0) ec = device_.select_input(config_.input);
  if (!ec) ec = device_.set_format(config_.width, config_.height, config_.format, format_);
  if (!ec) ec = device_.set_frame_rate(config_.fps, interval_);
  if (!ec) ec = device_.request_buffers(config_.buffer_count, format_.image_size);
  if (ec) device_.close();
  return ec;
}

std::error_code V4l2Camera::start_stream() noexcept {
  for (std::size_t i = 0; i < device_.buffer_count(); ++i)
    if (auto ec = device_.queue(static_cast<std::uint32_t>(i), 0)) return ec;
  if (auto ec = device_.stream_on()) return ec;
  held_.fill(false);
  held_count_ = 0;
  ++generation_;
  sequence_.reset();
  consecutive_errors_ = 0;
  last_frame_ = Clock::now();
  state_ = State::Streaming;
  return {};
}

void V4l2Camera::enter_recovering(std::error_code why) noexcept {
  last_error_ = why;
  ++counters_.recoveries_started;
  if (is_device_gone(why)) ++counters_.device_lost;
  device_.close();
  held_.fill(false);
  held_count_ = 0;
  ++generation_;
  sequence_.reset();
  state_ = State::Recovering;
  recovery_started_ = Clock::now();
  backoff_ = milliseconds{0};
  next_attempt_ = recovery_started_;  // the first reopen is immediate
}

void V4l2Camera::attempt_reopen() noexcept {
  ++counters_.reopen_attempts;
  std::error_code ec = open_stored();
  if (!ec) ec = start_stream();
  const Clock::time_point now = Clock::now();
  if (ec) {
    device_.close();
    last_error_ = ec;
    ++counters_.reopen_failures;
    backoff_ = backoff_.count() == 0 ? config_.backoff_min : std::min(backoff_ * 2, config_.backoff_max);
    next_attempt_ = now + backoff_;
    return;
  }
  ++counters_.reopen_successes;
  const std::int64_t took = duration_cast<nanoseconds>(now - recovery_started_).count();
  counters_.last_recovery_ns = took;
  counters_.max_recovery_ns = std::max(counters_.max_recovery_ns, took);
}

std::chrono::milliseconds V4l2Camera::recovery_wait() const noexcept {
  if (state_ != State::Recovering) return milliseconds{0};
  const auto now = Clock::now();
  return next_attempt_ > now ? duration_cast<milliseconds>(next_attempt_ - now) : milliseconds{0};
}

void V4l2Camera::note_streaming_error(std::error_code ec) noexcept {
  ++counters_.io_errors;
  if (is_fatal(ec) || ++consecutive_errors_ >= config_.max_consecutive_errors) {
    enter_recovering(ec);
  } else {
    last_error_ = ec;
  }
}

bool V4l2Camera::handle_buffer(const v4l2_buffer& buf, FrameView& out) noexcept {
  const std::uint32_t index = buf.index;  // range-checked by dequeue()
  if (held_[index]) {
    // The driver returned a buffer we never queued: do not hand it out twice.
    ++counters_.bad_buffers;
    return false;
  }
  const SequenceTracker::Step step = sequence_.update(buf.sequence);
  counters_.dropped += step.missed;
  if (step.restarted) ++counters_.sequence_restarts;

  const std::uint64_t needed = static_cast<std::uint64_t>(format_.stride) * (format_.height - 1) +
                               static_cast<std::uint64_t>(format_.width) * bytes_per_pixel(format_.format);
  const bool error_flag = (buf.flags & V4L2_BUF_FLAG_ERROR) != 0;
  const bool bad_size = buf.bytesused < needed || buf.bytesused > device_.buffer(index).length;
  if (error_flag || bad_size) {
    if (error_flag)
      ++counters_.buffer_errors;
    else
      ++counters_.bad_buffers;
    if (auto ec = device_.queue(index, 0)) note_streaming_error(ec);
    return false;
  }

  out.data = device_.buffer(index).data;
  out.bytes_used = buf.bytesused;
  out.width = format_.width;
  out.height = format_.height;
  out.stride = format_.stride;
  out.format = format_.format;
  out.sequence = buf.sequence;
  out.timestamp_ns = static_cast<std::int64_t>(buf.timestamp.tv_sec) * 1'000'000'000 +
                     static_cast<std::int64_t>(buf.timestamp.tv_usec) * 1'000;
  out.timestamp_monotonic = (buf.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
  out.index = index;
  out.generation = generation_;
  held_[index] = true;
  ++held_count_;
  ++counters_.frames;
  consecutive_errors_ = 0;
  last_frame_ = Clock::now();
  state_ = State::Streaming;
  return true;
}

std::error_code V4l2Camera::wait_frame(FrameView& out, std::chrono::milliseconds timeout) noexcept {
  const Clock::time_point deadline = Clock::now() + std::max(timeout, milliseconds{0});
  bool poll_error = false;
  for (;;) {
    const Clock::time_point now = Clock::now();
    if (state_ == State::Closed || state_ == State::Opened) return V4l2Error::NotStreaming;
    const std::optional<std::error_code> done = state_ == State::Recovering
                                                    ? wait_while_recovering(deadline, now)
                                                    : dequeue_or_sleep(out, deadline, now, poll_error);
    if (done) return *done;
  }
}

std::optional<std::error_code> V4l2Camera::wait_while_recovering(Clock::time_point deadline,
                                                                 Clock::time_point now) noexcept {
  if (now >= next_attempt_) {
    attempt_reopen();
    if (state_ != State::Recovering) return std::nullopt;
    now = Clock::now();
  }
  if (now >= deadline) {
    ++counters_.timeouts;
    return std::make_error_code(std::errc::timed_out);
  }
  int ignored = 0;
  (void)platform::sys_poll(nullptr, 0, milliseconds{ms_until(std::min(next_attempt_, deadline), now)},
                           ignored);
  return std::nullopt;
}

std::optional<std::error_code> V4l2Camera::dequeue_or_sleep(FrameView& out, Clock::time_point deadline,
                                                            Clock::time_point now,
                                                            bool& poll_error) noexcept {
  // Streaming or Stalled.
  if (held_count_ >= device_.buffer_count()) return V4l2Error::BuffersExhausted;
  v4l2_buffer buf{};
  const std::error_code ec = device_.dequeue(buf);
  if (!ec) {
    if (handle_buffer(buf, out)) return std::error_code{};
    return std::nullopt;
  }
  if (!platform::is_would_block(ec)) {
    note_streaming_error(ec);
    if (state_ == State::Recovering) return std::nullopt;
    return ec;
  }
  if (poll_error) {
    // poll() flagged an error but DQBUF has nothing: the queue is broken.
    note_streaming_error(platform::make_error(EIO));
    poll_error = false;
    return std::nullopt;
  }
  return sleep_until_ready(deadline, now, poll_error);
}

std::optional<std::error_code> V4l2Camera::sleep_until_ready(Clock::time_point deadline,
                                                             Clock::time_point now,
                                                             bool& poll_error) noexcept {
  // Nothing ready: sleep until a frame, the stall checks or the deadline.
  Clock::time_point wake = deadline;
  const Clock::time_point stall_at = last_frame_ + config_.frame_timeout;
  const Clock::time_point restart_at = stall_at + config_.stall_restart;
  if (state_ == State::Streaming) wake = std::min(wake, stall_at);
  if (state_ == State::Stalled && config_.stall_restart.count() > 0) wake = std::min(wake, restart_at);
  pollfd pfd{};
  pfd.fd = device_.fd();
  pfd.events = POLLIN;
  int ready = 0;
  if (auto pec = platform::sys_poll(&pfd, 1, milliseconds{ms_until(wake, now)}, ready)) {
    note_streaming_error(pec);
    if (state_ == State::Recovering) return std::nullopt;
    return pec;
  }
  if (ready > 0) {
    if ((pfd.revents & (POLLERR | POLLHUP | POLLNVAL)) != 0) {
      if ((pfd.revents & POLLHUP) != 0) {
        enter_recovering(platform::make_error(ENODEV));
        return std::nullopt;
      }
      poll_error = true;
    }
    return std::nullopt;  // DQBUF again
  }
  return check_stall(deadline, stall_at, restart_at);
}

std::optional<std::error_code> V4l2Camera::check_stall(Clock::time_point deadline, Clock::time_point stall_at,
                                                       Clock::time_point restart_at) noexcept {
  const Clock::time_point now = Clock::now();
  if (state_ == State::Streaming && now >= stall_at) {
    state_ = State::Stalled;
    ++counters_.stalls;
  }
  if (state_ == State::Stalled && config_.stall_restart.count() > 0 && now >= restart_at) {
    enter_recovering(std::make_error_code(std::errc::timed_out));
    return std::nullopt;
  }
  if (now >= deadline) {
    ++counters_.timeouts;
    return std::make_error_code(std::errc::timed_out);
  }
  return std::nullopt;
}

std::error_code V4l2Camera::release(const FrameView& frame) noexcept {
  if (frame.generation != generation_) return V4l2Error::StaleFrame;
  if (state_ != State::Streaming && state_ != State::Stalled) return V4l2Error::NotStreaming;
  if (frame.index >= device_.buffer_count() || !held_[frame.index])
    return std::make_error_code(std::errc::invalid_argument);
  held_[frame.index] = false;
  --held_count_;
  if (auto ec = device_.queue(frame.index, 0)) {
    note_streaming_error(ec);
    return ec;
  }
  return {};
}

}  // namespace markloop::v4l2
