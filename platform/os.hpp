// More of the OS for the ECU's loop and its map file: files written safely,
// signals and timers as descriptors, real-time scheduling, memory locking,
// and the systemd notification protocol (without libsystemd). As in
// syscall.hpp: EINTR retried, failures as std::error_code, no throw, no log.
#pragma once

#include <signal.h>

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string_view>
#include <system_error>

#include "platform/syscall.hpp"
#include "platform/unique_fd.hpp"

namespace markloop::platform {

// --- files -----------------------------------------------------------------
// open(2) with a creation mode.
std::error_code sys_open_mode(const char* path, int flags, unsigned mode, int& fd_out) noexcept;
// Writes all `size` bytes (short writes continued).
std::error_code write_all(int fd, const void* data, std::size_t size) noexcept;
// Reads up to `size` bytes, stopping only at end of file; `got` says how many.
std::error_code read_full(int fd, void* data, std::size_t size, std::size_t& got) noexcept;
std::error_code sys_fsync(int fd) noexcept;
std::error_code sys_rename(const char* from, const char* to) noexcept;
std::error_code sys_unlink(const char* path) noexcept;
// fsync of the directory holding `path`, so a rename in it is durable.
std::error_code sync_parent_directory(const char* path) noexcept;

// --- signals and timers as file descriptors ----------------------------------
// Blocks `signals` for the calling thread (before any other thread starts)
// and returns a non-blocking signalfd for them.
std::error_code open_signalfd(const sigset_t& signals, UniqueFd& out) noexcept;
// Next pending signal number, 0 when none.
std::error_code read_signal(int fd, int& signal_number) noexcept;
// Non-blocking CLOCK_MONOTONIC timerfd.
std::error_code open_timerfd(UniqueFd& out) noexcept;
// Arms the timer at an absolute CLOCK_MONOTONIC time, then every `period`
// (zero: once).
std::error_code arm_timer_absolute(int fd, std::chrono::nanoseconds deadline,
                                   std::chrono::nanoseconds period) noexcept;
// Expirations since the last read (more than 1: deadlines were missed);
// 0 when the timer has not fired.
std::error_code read_timer(int fd, std::uint64_t& expirations) noexcept;
// CLOCK_MONOTONIC now.
std::chrono::nanoseconds monotonic_now() noexcept;
// Sleeps until an absolute CLOCK_MONOTONIC time (EINTR: continues).
void sleep_until(std::chrono::nanoseconds deadline) noexcept;

// --- real time -----------------------------------------------------------------
std::error_code lock_all_memory() noexcept;                // mlockall(MCL_CURRENT|MCL_FUTURE)
std::error_code set_fifo_priority(int priority) noexcept;  // SCHED_FIFO for this thread
std::error_code pin_to_cpu(int cpu) noexcept;              // affinity of this thread
// Resident set size of this process in bytes (from /proc/self/statm): all,
// and anonymous only (heap, stacks, mappings: what a leak would grow; the
// rest is program text and files, paged in as code paths are first taken).
std::error_code resident_bytes(std::size_t& out) noexcept;
std::error_code anonymous_resident_bytes(std::size_t& out) noexcept;

// --- systemd ---------------------------------------------------------------------
// The sd_notify protocol: datagrams "READY=1", "WATCHDOG=1", "STOPPING=1",
// "STATUS=..." to the unix socket named in $NOTIFY_SOCKET ('@' = abstract).
// Not under systemd (no variable): every call is a no-op.
class SystemdNotifier {
 public:
  // Reads $NOTIFY_SOCKET and $WATCHDOG_USEC; opens the socket.
  std::error_code open() noexcept;
  bool enabled() const noexcept { return fd_.valid(); }
  // Half of WatchdogSec (when to ping), zero without a watchdog.
  std::chrono::nanoseconds watchdog_interval() const noexcept { return watchdog_interval_; }
  std::error_code notify(std::string_view message) noexcept;

 private:
  UniqueFd fd_;
  std::array<char, 108> path_{};  // sockaddr_un::sun_path
  std::size_t path_length_ = 0;
  std::chrono::nanoseconds watchdog_interval_{0};
};

}  // namespace markloop::platform
