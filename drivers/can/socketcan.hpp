// SocketCAN raw-socket driver: one object per CAN interface.
//
// States (explicit, see State):
//   Closed     --open() ok-->  Open
//   Open       --error frame BUSOFF-->  BusOff
//   Open       --ENETDOWN/ENXIO/ENODEV, repeated failures, TX stall-->  Recovering
//   BusOff     --error frame RESTARTED, or interface running again-->  Open
//   Recovering --interface up + reopen/rebind ok (tried with back-off)-->  Open
//   any        --close()-->  Closed
// Recovery is attempted on later calls (send/receive/flush_tx/poll_readable/
// service) once the back-off delay has passed; the delay doubles after each
// failed attempt up to Options::backoff_max.
//
// Rules: no exceptions, no heap after open(), every syscall through
// platform/syscall.hpp, counters instead of logging, every read checked
// against sizeof(struct can_frame) and len <= 8.
#pragma once

#include <linux/can.h>
#include <net/if.h>

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <system_error>

#include "drivers/can/can_frame.hpp"
#include "drivers/can/error_frame.hpp"
#include "drivers/can/tx_queue.hpp"
#include "platform/unique_fd.hpp"

namespace markloop::can {

static_assert(sizeof(struct can_frame) == 16, "classic CAN frame wire layout (CAN_MTU)");
static_assert(offsetof(struct can_frame, data) == 8, "can_frame payload offset");
static_assert(sizeof(struct can_filter) == 8, "can_filter layout");

struct ErrorClassCounters {
  std::uint64_t tx_timeout = 0;
  std::uint64_t lost_arbitration = 0;
  std::uint64_t controller = 0;
  std::uint64_t protocol = 0;
  std::uint64_t transceiver = 0;
  std::uint64_t no_ack = 0;
  std::uint64_t bus_off = 0;
  std::uint64_t bus_error = 0;
  std::uint64_t restarted = 0;
  std::uint64_t rx_overflow = 0;  // controller RX buffer overflow
  std::uint64_t tx_overflow = 0;
  std::uint64_t error_warning = 0;
  std::uint64_t error_passive = 0;
};

struct SocketCanCounters {
  // Receive path.
  std::uint64_t rx_frames = 0;        // data frames delivered by receive()
  std::uint64_t rx_errors = 0;        // recvmsg failures (not would-block, not down)
  std::uint64_t rx_bad_size = 0;      // byte count != sizeof(struct can_frame)
  std::uint64_t rx_bad_dlc = 0;       // len > 8
  std::uint64_t rx_remote = 0;        // remote (RTR) frames ignored
  std::uint64_t rx_dropped = 0;       // frames the kernel dropped (SO_RXQ_OVFL)
  std::uint64_t rx_no_timestamp = 0;  // no SCM_TIMESTAMPNS: host clock used
  std::uint64_t rx_ctrunc = 0;        // control data truncated (MSG_CTRUNC)
  // Transmit path.
  std::uint64_t tx_frames = 0;            // frames the kernel accepted
  std::uint64_t tx_errors = 0;            // write failures other than below
  std::uint64_t tx_short_writes = 0;      // write count != sizeof(struct can_frame)
  std::uint64_t tx_enobufs = 0;           // kernel/device queue full
  std::uint64_t tx_eagain = 0;            // socket send buffer full
  std::uint64_t tx_queue_drops = 0;       // oldest frames dropped from the app ring
  std::uint64_t tx_rejected = 0;          // send() while not Open, or invalid frame
  std::uint64_t tx_flushed_on_reset = 0;  // queued frames dropped when recovery began
  std::uint64_t tx_stalls = 0;            // nothing sent for Options::tx_stall_timeout
  // Error frames and state.
  std::uint64_t error_frames = 0;      // error frames read
  std::uint64_t error_frames_bad = 0;  // malformed error frames
  ErrorClassCounters error_classes{};
  std::uint64_t bus_off = 0;         // entries into BusOff
  std::uint64_t interface_down = 0;  // interface went down or vanished
  std::uint64_t resets = 0;          // entries into Recovering for other reasons
  std::uint64_t recovery_attempts = 0;
  std::uint64_t recovery_failures = 0;
  std::uint64_t restarts = 0;  // returns to Open after BusOff/Recovering
};

class SocketCan final : public CanFrameSink {
 public:
  enum class State { Closed, Open, BusOff, Recovering };

  static constexpr std::size_t kTxQueueCapacity = 32;
  static constexpr std::size_t kMaxFilters = 32;

  struct Options {
    std::chrono::milliseconds backoff_initial{20};
    std::chrono::milliseconds backoff_max{1000};
    // Consecutive unexplained receive/transmit failures before a reset.
    unsigned max_consecutive_errors = 8;
    // Queued frames that could not be sent for this long cause a reset
    // (counted in tx_stalls); 0 disables.
    std::chrono::milliseconds tx_stall_timeout{2000};
    // SO_RCVBUF in bytes; 0 keeps the kernel default.
    int receive_buffer_bytes = 0;
    // Receive error frames (CAN_RAW_ERR_FILTER = CAN_ERR_MASK).
    bool error_frames = true;
  };

  SocketCan() = default;
  ~SocketCan() override { close(); }
  SocketCan(const SocketCan&) = delete;
  SocketCan& operator=(const SocketCan&) = delete;
  SocketCan(SocketCan&&) = delete;
  SocketCan& operator=(SocketCan&&) = delete;

  // Creates a raw CAN socket bound to `interface` with the given receive
  // filters (empty: no data frames, error frames only) and options.
  // Closed -> Open on success; on failure stays Closed and returns why
  // (e.g. EAFNOSUPPORT without CAN in the kernel, ENODEV for a missing
  // interface, ENETDOWN when it is down, EINVAL for bad arguments).
  std::error_code open(std::string_view interface, std::span<const CanFilter> filters,
                       const Options& options) noexcept;
  std::error_code open(std::string_view interface, std::span<const CanFilter> filters) noexcept {
    return open(interface, filters, Options{});
  }
  // Closes the socket and drops queued frames. Safe to call any number of times.
  void close() noexcept;

  State state() const noexcept { return state_; }
  const SocketCanCounters& counters() const noexcept { return counters_; }
  std::string_view interface() const noexcept { return {ifname_.data(), ifname_len_}; }
  // The socket for an external event loop (POLLIN; POLLOUT while
  // tx_pending()); -1 while Closed or Recovering.
  int fd() const noexcept { return fd_.get(); }

  // CanFrameSink: validates and queues `frame`, then flushes. Never blocks.
  // {} when accepted; when the ring is full the oldest queued frame is
  // dropped. Errors: invalid_argument (bad id/dlc), not_connected (Closed),
  // network_down (Recovering or the interface just went down),
  // network_unreachable (BusOff).
  std::error_code send(const CanFrame& frame) noexcept override;
  // Sends queued frames until the queue is empty or the kernel pushes back
  // (EAGAIN/ENOBUFS: {} is returned, frames stay queued).
  std::error_code flush_tx() noexcept;
  std::size_t tx_pending() const noexcept { return tx_.size(); }

  // Reads the next data frame into `out` (timestamp from the kernel).
  // Error frames are consumed and decoded on the way (at most 64 per call,
  // so an error-frame storm cannot starve the caller's loop). Returns {} with
  // a frame, resource_unavailable_try_again when nothing (more) is pending
  // for now, or the state errors of send(). Counters are cumulative over the
  // object's lifetime (open()/close() do not reset them).
  std::error_code receive(CanFrame& out) noexcept;

  // Waits up to `timeout` for receive() to have something to do ({}), or
  // returns timed_out. While Recovering it sleeps and retries recovery
  // instead of busy-looping. Negative timeout waits forever.
  std::error_code poll_readable(std::chrono::milliseconds timeout) noexcept;

  // Housekeeping for an external event loop: attempts recovery when due,
  // flushes the queue, checks for a TX stall.
  void service() noexcept;
  // Time until the next recovery attempt (zero when due or not recovering).
  std::chrono::milliseconds recovery_wait() const noexcept;

  // The error frame decoder applied to a frame as if it had been read from
  // the socket: updates counters and state. Public for tests and for
  // error frames obtained elsewhere.
  void handle_error_frame(const struct can_frame& frame) noexcept;

 private:
  using Clock = std::chrono::steady_clock;

  std::error_code open_socket() noexcept;        // (re)creates fd_ from the stored config
  std::error_code interface_running() noexcept;  // {} when IFF_UP and IFF_RUNNING
  void enter_recovering(bool interface_down) noexcept;
  void enter_open_after_recovery() noexcept;
  bool maybe_recover() noexcept;  // returns true when usable (Open)
  void schedule_retry() noexcept;
  void apply_pending() noexcept;
  std::error_code state_error() const noexcept;
  TxOutcome transmit(const CanFrame& frame) noexcept;
  void note_failure() noexcept;
  void check_tx_stall() noexcept;

  // A state change decided inside a TX flush, applied after it.
  enum class Pending { None, Down, Reset };

  platform::UniqueFd fd_;
  Pending pending_ = Pending::None;
  State state_ = State::Closed;
  std::array<char, IFNAMSIZ> ifname_{};
  std::size_t ifname_len_ = 0;
  std::array<struct can_filter, kMaxFilters> filters_{};
  std::size_t filter_count_ = 0;
  Options options_{};
  TxQueue<kTxQueueCapacity> tx_;
  SocketCanCounters counters_{};
  std::uint32_t last_ovfl_ = 0;  // kernel drop counter of the current socket
  unsigned consecutive_errors_ = 0;
  std::chrono::milliseconds backoff_{0};
  Clock::time_point next_attempt_{};
  Clock::time_point last_tx_progress_{};
};

const char* to_string(SocketCan::State state) noexcept;

}  // namespace markloop::can
