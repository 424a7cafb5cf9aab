#include "drivers/can/socketcan.hpp"

#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "platform/syscall.hpp"

namespace markloop::can {

namespace {

using platform::make_error;

bool is_interface_gone(const std::error_code& ec) noexcept {
  if (ec.category() != std::system_category()) return false;
  return ec.value() == ENETDOWN || ec.value() == ENXIO || ec.value() == ENODEV;
}

std::int64_t realtime_ns() noexcept {
  timespec ts{};
  ::clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// Receive buffer big enough for any CAN MTU, so that a frame of the wrong
// size shows up as a wrong byte count instead of being silently truncated.
union RxBuffer {
  struct can_frame classic;
  struct canfd_frame fd;
};
static_assert(sizeof(RxBuffer) == CANFD_MTU);

constexpr std::size_t kControlBytes = CMSG_SPACE(sizeof(struct timespec)) + CMSG_SPACE(sizeof(std::uint32_t));

}  // namespace

const char* to_string(SocketCan::State state) noexcept {
  switch (state) {
    case SocketCan::State::Closed:
      return "Closed";
    case SocketCan::State::Open:
      return "Open";
    case SocketCan::State::BusOff:
      return "BusOff";
    case SocketCan::State::Recovering:
      return "Recovering";
  }
  return "?";
}

std::error_code SocketCan::open(std::string_view interface, std::span<const CanFilter> filters,
                                const Options& options) noexcept {
  close();
  if (interface.empty() || interface.size() >= IFNAMSIZ || filters.size() > kMaxFilters ||
      options.backoff_initial.count() <= 0 || options.backoff_max < options.backoff_initial)
    return std::make_error_code(std::errc::invalid_argument);
  for (const CanFilter& f : filters) {
    const std::uint32_t limit = f.extended ? CanFrame::kMaxExtendedId : CanFrame::kMaxStandardId;
    if (f.id > limit) return std::make_error_code(std::errc::invalid_argument);
  }

  ifname_.fill('\0');
  std::memcpy(ifname_.data(), interface.data(), interface.size());
  ifname_len_ = interface.size();
  filter_count_ = filters.size();
  for (std::size_t i = 0; i < filters.size(); ++i) {
    const CanFilter& f = filters[i];
    const std::uint32_t limit = f.extended ? CanFrame::kMaxExtendedId : CanFrame::kMaxStandardId;
    // The format bit and the RTR bit are always part of the match: only data
    // frames of the requested format pass.
    filters_[i].can_id = (f.id & limit) | (f.extended ? CAN_EFF_FLAG : 0U);
    filters_[i].can_mask = (f.mask & limit) | CAN_EFF_FLAG | CAN_RTR_FLAG;
  }
  options_ = options;

  if (const std::error_code ec = open_socket()) return ec;
  state_ = State::Open;
  consecutive_errors_ = 0;
  backoff_ = options_.backoff_initial;
  last_tx_progress_ = Clock::now();
  return {};
}

void SocketCan::close() noexcept {
  fd_.reset();
  tx_.clear();
  state_ = State::Closed;
  pending_ = Pending::None;
}

std::error_code SocketCan::open_socket() noexcept {
  int raw = -1;
  if (auto ec = platform::sys_socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW, raw))
    return ec;
  platform::UniqueFd sock(raw);

  struct ifreq ifr {};
  std::memcpy(ifr.ifr_name, ifname_.data(), ifname_len_);
  if (auto ec = platform::sys_ioctl(sock.get(), SIOCGIFINDEX, &ifr)) return ec;
  const int ifindex = ifr.ifr_ifindex;

  const void* filter_data = filter_count_ > 0 ? filters_.data() : nullptr;
  if (auto ec = platform::sys_setsockopt(sock.get(), SOL_CAN_RAW, CAN_RAW_FILTER, filter_data,
                                         static_cast<unsigned>(filter_count_ * sizeof(can_filter))))
    return ec;
  const can_err_mask_t err_mask = options_.error_frames ? CAN_ERR_MASK : 0U;
  if (auto ec =
          platform::sys_setsockopt(sock.get(), SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof(err_mask)))
    return ec;
  const int one = 1;
  if (auto ec = platform::sys_setsockopt(sock.get(), SOL_SOCKET, SO_TIMESTAMPNS, &one, sizeof(one)))
    return ec;
  if (auto ec = platform::sys_setsockopt(sock.get(), SOL_SOCKET, SO_RXQ_OVFL, &one, sizeof(one))) return ec;
  if (options_.receive_buffer_bytes > 0) {
    const int bytes = options_.receive_buffer_bytes;
    if (auto ec = platform::sys_setsockopt(sock.get(), SOL_SOCKET, SO_RCVBUF, &bytes, sizeof(bytes)))
      return ec;
  }

  struct sockaddr_can addr {};
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifindex;
  if (auto ec = platform::sys_bind(sock.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)))
    return ec;

  // bind() succeeds on an interface that is down; insist that it is usable.
  struct ifreq flags {};
  std::memcpy(flags.ifr_name, ifname_.data(), ifname_len_);
  if (auto ec = platform::sys_ioctl(sock.get(), SIOCGIFFLAGS, &flags)) return ec;
  if ((flags.ifr_flags & IFF_UP) == 0 || (flags.ifr_flags & IFF_RUNNING) == 0) return make_error(ENETDOWN);

  fd_ = std::move(sock);
  last_ovfl_ = 0;
  return {};
}

std::error_code SocketCan::interface_running() noexcept {
  if (!fd_) return make_error(EBADF);
  struct ifreq flags {};
  std::memcpy(flags.ifr_name, ifname_.data(), ifname_len_);
  if (auto ec = platform::sys_ioctl(fd_.get(), SIOCGIFFLAGS, &flags)) return ec;
  if ((flags.ifr_flags & IFF_UP) == 0 || (flags.ifr_flags & IFF_RUNNING) == 0) return make_error(ENETDOWN);
  return {};
}

void SocketCan::enter_recovering(bool interface_down) noexcept {
  if (state_ == State::Closed) return;
  if (interface_down)
    ++counters_.interface_down;
  else
    ++counters_.resets;
  counters_.tx_flushed_on_reset += tx_.clear();
  fd_.reset();
  state_ = State::Recovering;
  consecutive_errors_ = 0;
  backoff_ = options_.backoff_initial;
  next_attempt_ = Clock::now() + backoff_;
}

void SocketCan::enter_open_after_recovery() noexcept {
  state_ = State::Open;
  ++counters_.restarts;
  consecutive_errors_ = 0;
  backoff_ = options_.backoff_initial;
  last_tx_progress_ = Clock::now();
}

void SocketCan::schedule_retry() noexcept {
  ++counters_.recovery_failures;
  backoff_ = std::min(backoff_ * 2, options_.backoff_max);
  next_attempt_ = Clock::now() + backoff_;
}

bool SocketCan::maybe_recover() noexcept {
  apply_pending();
  if (state_ == State::Open) return true;
  if (state_ == State::Closed) return false;
  if (Clock::now() < next_attempt_) return false;
  ++counters_.recovery_attempts;
  if (state_ == State::BusOff) {
    // The controller restarts on its own (restart-ms) and brings the carrier
    // back; until then the interface is not RUNNING.
    if (const std::error_code ec = interface_running(); !ec) {
      enter_open_after_recovery();
      return true;
    } else if (is_interface_gone(ec) && ec.value() != ENETDOWN) {
      enter_recovering(true);
      return false;
    }
    schedule_retry();
    return false;
  }
  if (!open_socket()) {
    enter_open_after_recovery();
    return true;
  }
  schedule_retry();
  return false;
}

std::chrono::milliseconds SocketCan::recovery_wait() const noexcept {
  if (state_ != State::Recovering && state_ != State::BusOff) return std::chrono::milliseconds{0};
  const auto left = std::chrono::ceil<std::chrono::milliseconds>(next_attempt_ - Clock::now());
  return std::max(left, std::chrono::milliseconds{0});
}

std::error_code SocketCan::state_error() const noexcept {
  switch (state_) {
    case State::Open:
      return {};
    case State::Closed:
      return std::make_error_code(std::errc::not_connected);
    case State::BusOff:
      return std::make_error_code(std::errc::network_unreachable);
    case State::Recovering:
      return std::make_error_code(std::errc::network_down);
  }
  return std::make_error_code(std::errc::not_connected);
}

void SocketCan::note_failure() noexcept {
  if (++consecutive_errors_ >= options_.max_consecutive_errors && pending_ == Pending::None)
    pending_ = Pending::Reset;
}

void SocketCan::apply_pending() noexcept {
  const Pending p = std::exchange(pending_, Pending::None);
  if (p == Pending::Down) enter_recovering(true);
  if (p == Pending::Reset) enter_recovering(false);
}

TxOutcome SocketCan::transmit(const CanFrame& frame) noexcept {
  struct can_frame cf {};
  cf.can_id = frame.id | (frame.extended ? CAN_EFF_FLAG : 0U);
  cf.len = frame.dlc;
  std::memcpy(cf.data, frame.data.data(), frame.dlc);
  const platform::IoResult r = platform::sys_write(fd_.get(), &cf, sizeof(cf));
  if (!r.error) {
    if (r.bytes != sizeof(cf)) {
      ++counters_.tx_short_writes;
      note_failure();
      return TxOutcome::Discard;
    }
    ++counters_.tx_frames;
    consecutive_errors_ = 0;
    return TxOutcome::Sent;
  }
  if (platform::is_would_block(r.error)) {
    ++counters_.tx_eagain;
    return TxOutcome::RetryLater;
  }
  if (r.error.value() == ENOBUFS) {
    ++counters_.tx_enobufs;
    return TxOutcome::RetryLater;
  }
  if (is_interface_gone(r.error)) {
    pending_ = Pending::Down;
    return TxOutcome::Abort;
  }
  ++counters_.tx_errors;
  note_failure();
  if (pending_ != Pending::None) return TxOutcome::Abort;
  return TxOutcome::Discard;
}

std::error_code SocketCan::send(const CanFrame& frame) noexcept {
  if (!frame.valid()) {
    ++counters_.tx_rejected;
    return std::make_error_code(std::errc::invalid_argument);
  }
  if (!maybe_recover()) {
    ++counters_.tx_rejected;
    return state_error();
  }
  if (tx_.empty()) last_tx_progress_ = Clock::now();
  if (tx_.push(frame)) ++counters_.tx_queue_drops;
  return flush_tx();
}

std::error_code SocketCan::flush_tx() noexcept {
  if (!maybe_recover()) return state_error();
  const FlushResult result = tx_.flush([this](const CanFrame& f) { return transmit(f); });
  if (result.sent > 0 || tx_.empty()) last_tx_progress_ = Clock::now();
  apply_pending();
  if (state_ != State::Open) return state_error();
  if (result.stopped_by == TxOutcome::RetryLater) check_tx_stall();
  return state_error();
}

void SocketCan::check_tx_stall() noexcept {
  if (options_.tx_stall_timeout.count() <= 0 || tx_.empty() || state_ != State::Open) return;
  if (Clock::now() - last_tx_progress_ > options_.tx_stall_timeout) {
    ++counters_.tx_stalls;
    enter_recovering(false);
  }
}

void SocketCan::service() noexcept {
  if (!maybe_recover()) return;
  if (!tx_.empty()) (void)flush_tx();
}

void SocketCan::handle_error_frame(const struct can_frame& frame) noexcept {
  ++counters_.error_frames;
  const ErrorFrameInfo info = decode_error_frame(frame);
  if (!info.valid) {
    ++counters_.error_frames_bad;
    return;
  }
  ErrorClassCounters& c = counters_.error_classes;
  c.tx_timeout += info.tx_timeout;
  c.lost_arbitration += info.lost_arbitration;
  c.controller += info.controller;
  c.protocol += info.protocol;
  c.transceiver += info.transceiver;
  c.no_ack += info.no_ack;
  c.bus_off += info.bus_off;
  c.bus_error += info.bus_error;
  c.restarted += info.restarted;
  c.rx_overflow += info.rx_overflow;
  c.tx_overflow += info.tx_overflow;
  c.error_warning += info.error_warning;
  c.error_passive += info.error_passive;

  if (info.bus_off && state_ == State::Open) {
    state_ = State::BusOff;
    ++counters_.bus_off;
    counters_.tx_flushed_on_reset += tx_.clear();
    backoff_ = options_.backoff_initial;
    next_attempt_ = Clock::now() + backoff_;
  } else if (info.restarted && state_ == State::BusOff) {
    enter_open_after_recovery();
  }
}

std::error_code SocketCan::receive(CanFrame& out) noexcept {
  maybe_recover();
  if (state_ != State::Open && state_ != State::BusOff) return state_error();

  constexpr int kBudget = 64;  // error frames consumed per call at most
  for (int i = 0; i < kBudget; ++i) {
    RxBuffer buf{};
    struct iovec iov {};
    iov.iov_base = &buf;
    iov.iov_len = sizeof(buf);
    alignas(struct cmsghdr) unsigned char control[kControlBytes];
    struct msghdr msg {};
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control;
    msg.msg_controllen = sizeof(control);

    const platform::IoResult r = platform::sys_recvmsg(fd_.get(), &msg, MSG_DONTWAIT);
    if (r.error) {
      if (platform::is_would_block(r.error))
        return std::make_error_code(std::errc::resource_unavailable_try_again);
      if (is_interface_gone(r.error)) {
        enter_recovering(true);
        return state_error();
      }
      ++counters_.rx_errors;
      note_failure();
      apply_pending();
      return r.error;
    }
    if (r.bytes != sizeof(struct can_frame)) {
      ++counters_.rx_bad_size;
      continue;
    }
    if (msg.msg_flags & MSG_CTRUNC) ++counters_.rx_ctrunc;

    std::int64_t stamp = 0;
    for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
      if (c->cmsg_level != SOL_SOCKET) continue;
      if (c->cmsg_type == SCM_TIMESTAMPNS && c->cmsg_len >= CMSG_LEN(sizeof(struct timespec))) {
        struct timespec ts {};
        std::memcpy(&ts, CMSG_DATA(c), sizeof(ts));
        stamp = static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
      } else if (c->cmsg_type == SO_RXQ_OVFL && c->cmsg_len >= CMSG_LEN(sizeof(std::uint32_t))) {
        std::uint32_t drops = 0;
        std::memcpy(&drops, CMSG_DATA(c), sizeof(drops));
        counters_.rx_dropped += static_cast<std::uint32_t>(drops - last_ovfl_);  // wraps
        last_ovfl_ = drops;
      }
    }

    const struct can_frame& cf = buf.classic;
    if (cf.can_id & CAN_ERR_FLAG) {
      handle_error_frame(cf);
      continue;
    }
    if (cf.can_id & CAN_RTR_FLAG) {
      ++counters_.rx_remote;
      continue;
    }
    if (cf.len > CAN_MAX_DLEN) {
      ++counters_.rx_bad_dlc;
      continue;
    }
    if (stamp == 0) {
      ++counters_.rx_no_timestamp;
      stamp = realtime_ns();
    }
    out = CanFrame{};
    out.extended = (cf.can_id & CAN_EFF_FLAG) != 0;
    out.id = cf.can_id & (out.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
    out.dlc = cf.len;
    std::memcpy(out.data.data(), cf.data, cf.len);
    out.timestamp_ns = stamp;
    ++counters_.rx_frames;
    consecutive_errors_ = 0;
    return {};
  }
  return std::make_error_code(std::errc::resource_unavailable_try_again);
}

std::error_code SocketCan::poll_readable(std::chrono::milliseconds timeout) noexcept {
  const bool forever = timeout.count() < 0;
  const Clock::time_point deadline = Clock::now() + (forever ? std::chrono::milliseconds{0} : timeout);
  for (;;) {
    maybe_recover();
    if (state_ == State::Closed) return state_error();
    std::chrono::milliseconds wait{-1};
    if (!forever) {
      wait = std::max(std::chrono::ceil<std::chrono::milliseconds>(deadline - Clock::now()),
                      std::chrono::milliseconds{0});
    }
    if (state_ != State::Open) {
      // Wake up for the next recovery attempt.
      const std::chrono::milliseconds rw = recovery_wait();
      wait = (wait.count() < 0) ? rw : std::min(wait, rw);
    }
    struct pollfd pfd {};
    pfd.fd = fd_.get();  // -1 while Recovering: poll() then just sleeps
    pfd.events = POLLIN;
    int ready = 0;
    if (auto ec = platform::sys_poll(&pfd, 1, wait, ready)) return ec;
    if (ready > 0 && fd_) return {};  // POLLIN, or POLLERR: receive() will see why
    if (!forever && Clock::now() >= deadline) return std::make_error_code(std::errc::timed_out);
  }
}

}  // namespace markloop::can
