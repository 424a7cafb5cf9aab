#include "drivers/v4l2/v4l2_output.hpp"

#include <poll.h>

#include <algorithm>
#include <cstring>

#include "platform/syscall.hpp"

namespace markloop::v4l2 {

namespace {

using std::chrono::milliseconds;
using Clock = std::chrono::steady_clock;

int ms_until(Clock::time_point t, Clock::time_point now) noexcept {
  if (t <= now) return 0;
  const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(t - now).count();
  const auto ms = (ns + 999'999) / 1'000'000;
  return ms > 60'000 ? 60'000 : static_cast<int>(ms);
}

}  // namespace

const char* to_string(V4l2Output::State state) noexcept {
  switch (state) {
    case V4l2Output::State::Closed:
      return "Closed";
    case V4l2Output::State::Opened:
      return "Opened";
    case V4l2Output::State::Streaming:
      return "Streaming";
  }
  return "?";
}

std::error_code V4l2Output::validate(const OutputConfig& c) noexcept {
  const bool ok = !c.device.empty() && c.device.size() < kMaxPath &&
                  c.device.find('\0') == std::string_view::npos && c.output >= -1 && c.width > 0 &&
                  c.width <= 16384 && c.height > 0 && c.height <= 16384 &&
                  (c.format != PixelFormat::Yuyv || c.width % 2 == 0) && c.fps <= 1000 &&
                  c.buffer_count >= 1 && c.buffer_count <= V4l2Device::kMaxBuffers;
  return ok ? std::error_code{} : std::make_error_code(std::errc::invalid_argument);
}

std::error_code V4l2Output::open(const OutputConfig& config) noexcept {
  stop();
  if (auto ec = validate(config)) return ec;
  path_.fill('\0');
  std::memcpy(path_.data(), config.device.data(), config.device.size());
  std::error_code ec = device_.open(path_.data(), V4l2Device::Direction::Output, info_);
  if (!ec && config.output >= 0) ec = device_.select_output(config.output);
  if (!ec) ec = device_.set_format(config.width, config.height, config.format, format_);
  if (!ec) ec = device_.set_frame_rate(config.fps, interval_);
  if (!ec) ec = device_.request_buffers(config.buffer_count, format_.image_size);
  if (ec) {
    device_.close();
    return ec;
  }
  slots_.fill(Slot::Free);
  ++generation_;
  state_ = State::Opened;
  return {};
}

std::error_code V4l2Output::start() noexcept {
  if (state_ == State::Streaming) return {};
  if (state_ != State::Opened) return V4l2Error::NotStreaming;
  if (auto ec = device_.stream_on()) return ec;
  state_ = State::Streaming;
  return {};
}

std::error_code V4l2Output::start(const OutputConfig& config) noexcept {
  if (auto ec = open(config)) return ec;
  if (auto ec = start()) {
    stop();
    return ec;
  }
  return {};
}

void V4l2Output::stop() noexcept {
  device_.close();
  slots_.fill(Slot::Free);
  ++generation_;
  state_ = State::Closed;
}

std::error_code V4l2Output::acquire(OutputBuffer& out, std::chrono::milliseconds timeout) noexcept {
  if (state_ != State::Streaming) return V4l2Error::NotStreaming;
  const Clock::time_point deadline = Clock::now() + std::max(timeout, milliseconds{0});
  for (;;) {
    // Reclaim everything the driver has finished with.
    for (;;) {
      v4l2_buffer buf{};
      const std::error_code ec = device_.dequeue(buf);
      if (platform::is_would_block(ec)) break;
      if (ec) {
        ++counters_.io_errors;
        return ec;
      }
      if (slots_[buf.index] != Slot::Queued) {
        ++counters_.io_errors;  // a buffer we did not queue
        continue;
      }
      ++counters_.frames_done;
      if ((buf.flags & V4L2_BUF_FLAG_ERROR) != 0) ++counters_.buffer_errors;
      slots_[buf.index] = Slot::Free;
    }
    for (std::size_t i = 0; i < device_.buffer_count(); ++i) {
      if (slots_[i] != Slot::Free) continue;
      slots_[i] = Slot::Acquired;
      const MappedBuffer& m = device_.buffer(i);
      out.data = m.data;
      out.capacity = static_cast<std::uint32_t>(m.length);
      out.width = format_.width;
      out.height = format_.height;
      out.stride = format_.stride;
      out.image_size = format_.image_size;
      out.format = format_.format;
      out.index = static_cast<std::uint32_t>(i);
      out.generation = generation_;
      return {};
    }
    const Clock::time_point now = Clock::now();
    if (now >= deadline) {
      ++counters_.timeouts;
      return std::make_error_code(std::errc::timed_out);
    }
    pollfd pfd{};
    pfd.fd = device_.fd();
    pfd.events = POLLOUT;
    int ready = 0;
    if (auto ec = platform::sys_poll(&pfd, 1, milliseconds{ms_until(deadline, now)}, ready)) {
      ++counters_.io_errors;
      return ec;
    }
    if (ready > 0 && (pfd.revents & (POLLERR | POLLHUP | POLLNVAL)) != 0 && (pfd.revents & POLLOUT) == 0) {
      ++counters_.io_errors;
      return platform::make_error((pfd.revents & POLLHUP) != 0 ? ENODEV : EIO);
    }
  }
}

std::error_code V4l2Output::submit(const OutputBuffer& buffer, std::uint32_t bytes_used) noexcept {
  if (state_ != State::Streaming) return V4l2Error::NotStreaming;
  if (buffer.generation != generation_) return V4l2Error::StaleFrame;
  if (buffer.index >= device_.buffer_count() || slots_[buffer.index] != Slot::Acquired || bytes_used == 0 ||
      bytes_used > buffer.capacity)
    return std::make_error_code(std::errc::invalid_argument);
  if (auto ec = device_.queue(buffer.index, bytes_used)) {
    ++counters_.io_errors;
    slots_[buffer.index] = Slot::Free;
    return ec;
  }
  slots_[buffer.index] = Slot::Queued;
  ++counters_.frames_queued;
  return {};
}

std::error_code V4l2Output::send_luma(std::span<const std::uint8_t> luma,
                                      std::chrono::milliseconds timeout) noexcept {
  if (state_ != State::Streaming) return V4l2Error::NotStreaming;
  if (luma.size() != static_cast<std::size_t>(format_.width) * format_.height)
    return std::make_error_code(std::errc::invalid_argument);
  OutputBuffer buffer;
  if (auto ec = acquire(buffer, timeout)) return ec;
  if (!fill_from_luma(format_.format, luma, format_.width, format_.height, format_.stride,
                      std::span<std::uint8_t>(buffer.data, buffer.capacity))) {
    slots_[buffer.index] = Slot::Free;
    return V4l2Error::BufferTooSmall;
  }
  return submit(buffer, format_.image_size);
}

}  // namespace markloop::v4l2
