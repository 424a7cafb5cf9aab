#include "platform/os.hpp"
#include "platform/retry_eintr.hpp"

#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/signalfd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/timerfd.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace markloop::platform {

namespace {

using detail::retry_eintr;

std::error_code result(int r) noexcept {
  return r < 0 ? last_error() : std::error_code{};
}

timespec to_timespec(std::chrono::nanoseconds t) noexcept {
  const auto ns = t.count() < 0 ? 0 : t.count();
  return {static_cast<time_t>(ns / 1000000000), static_cast<long>(ns % 1000000000)};
}

}  // namespace

std::error_code sys_open_mode(const char* path, int flags, unsigned mode, int& fd_out) noexcept {
  fd_out = retry_eintr([&] { return ::open(path, flags | O_CLOEXEC, static_cast<mode_t>(mode)); });
  return result(fd_out);
}

std::error_code write_all(int fd, const void* data, std::size_t size) noexcept {
  const auto* bytes = static_cast<const std::uint8_t*>(data);
  while (size > 0) {
    const IoResult r = sys_write(fd, bytes, size);
    if (r.error) return r.error;
    if (r.bytes == 0) return make_error(EIO);
    bytes += r.bytes;
    size -= r.bytes;
  }
  return {};
}

std::error_code read_full(int fd, void* data, std::size_t size, std::size_t& got) noexcept {
  auto* bytes = static_cast<std::uint8_t*>(data);
  got = 0;
  while (got < size) {
    const IoResult r = sys_read(fd, bytes + got, size - got);
    if (r.error) return r.error;
    if (r.bytes == 0) break;
    got += r.bytes;
  }
  return {};
}

std::error_code sys_fsync(int fd) noexcept {
  return result(retry_eintr([&] { return ::fsync(fd); }));
}

std::error_code sys_rename(const char* from, const char* to) noexcept {
  return result(retry_eintr([&] { return ::rename(from, to); }));
}

std::error_code sys_unlink(const char* path) noexcept {
  return result(retry_eintr([&] { return ::unlink(path); }));
}

std::error_code sync_parent_directory(const char* path) noexcept {
  std::array<char, 4096> directory{};
  const char* slash = std::strrchr(path, '/');
  if (slash == nullptr) {
    directory[0] = '.';
  } else {
    const std::size_t length = slash == path ? 1 : static_cast<std::size_t>(slash - path);
    if (length >= directory.size()) return make_error(ENAMETOOLONG);
    std::memcpy(directory.data(), path, length);
  }
  int fd = -1;
  if (auto ec = sys_open_mode(directory.data(), O_RDONLY | O_DIRECTORY, 0, fd)) return ec;
  const UniqueFd owner(fd);
  return sys_fsync(fd);
}

std::error_code open_signalfd(const sigset_t& signals, UniqueFd& out) noexcept {
  if (const int r = ::pthread_sigmask(SIG_BLOCK, &signals, nullptr); r != 0) return make_error(r);
  const int fd = ::signalfd(-1, &signals, SFD_NONBLOCK | SFD_CLOEXEC);
  if (fd < 0) return last_error();
  out = UniqueFd(fd);
  return {};
}

std::error_code read_signal(int fd, int& signal_number) noexcept {
  signal_number = 0;
  signalfd_siginfo info{};
  const IoResult r = sys_read(fd, &info, sizeof info);
  if (r.error) return is_would_block(r.error) ? std::error_code{} : r.error;
  if (r.bytes != sizeof info) return make_error(EIO);
  signal_number = static_cast<int>(info.ssi_signo);
  return {};
}

std::error_code open_timerfd(UniqueFd& out) noexcept {
  const int fd = ::timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC);
  if (fd < 0) return last_error();
  out = UniqueFd(fd);
  return {};
}

std::error_code arm_timer_absolute(int fd, std::chrono::nanoseconds deadline,
                                   std::chrono::nanoseconds period) noexcept {
  itimerspec spec{};
  spec.it_value = to_timespec(deadline);
  if (spec.it_value.tv_sec == 0 && spec.it_value.tv_nsec == 0) spec.it_value.tv_nsec = 1;
  spec.it_interval = to_timespec(period);
  return result(::timerfd_settime(fd, TFD_TIMER_ABSTIME, &spec, nullptr));
}

std::error_code read_timer(int fd, std::uint64_t& expirations) noexcept {
  expirations = 0;
  const IoResult r = sys_read(fd, &expirations, sizeof expirations);
  if (r.error) return is_would_block(r.error) ? std::error_code{} : r.error;
  if (r.bytes != sizeof expirations) return make_error(EIO);
  return {};
}

std::chrono::nanoseconds monotonic_now() noexcept {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return std::chrono::seconds(ts.tv_sec) + std::chrono::nanoseconds(ts.tv_nsec);
}

void sleep_until(std::chrono::nanoseconds deadline) noexcept {
  const timespec ts = to_timespec(deadline);
  while (::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

std::error_code lock_all_memory() noexcept {
  return result(::mlockall(MCL_CURRENT | MCL_FUTURE));
}

std::error_code set_fifo_priority(int priority) noexcept {
  sched_param param{};
  param.sched_priority = priority;
  const int r = ::pthread_setschedparam(::pthread_self(), SCHED_FIFO, &param);
  return r == 0 ? std::error_code{} : make_error(r);
}

std::error_code pin_to_cpu(int cpu) noexcept {
  if (cpu < 0 || cpu >= CPU_SETSIZE) return make_error(EINVAL);
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(static_cast<std::size_t>(cpu), &set);
  const int r = ::pthread_setaffinity_np(::pthread_self(), sizeof set, &set);
  return r == 0 ? std::error_code{} : make_error(r);
}

namespace {
std::error_code read_statm(unsigned long& resident_pages, unsigned long& shared_pages) noexcept {
  int fd = -1;
  if (auto ec = sys_open_mode("/proc/self/statm", O_RDONLY, 0, fd)) return ec;
  const UniqueFd owner(fd);
  std::array<char, 128> text{};
  std::size_t got = 0;
  if (auto ec = read_full(fd, text.data(), text.size() - 1, got)) return ec;
  unsigned long size_pages = 0;
  if (std::sscanf(text.data(), "%lu %lu %lu", &size_pages, &resident_pages, &shared_pages) != 3)
    return make_error(EIO);
  return {};
}
}  // namespace

std::error_code resident_bytes(std::size_t& out) noexcept {
  unsigned long resident = 0, shared = 0;
  if (auto ec = read_statm(resident, shared)) return ec;
  out = resident * static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  return {};
}

std::error_code anonymous_resident_bytes(std::size_t& out) noexcept {
  unsigned long resident = 0, shared = 0;
  if (auto ec = read_statm(resident, shared)) return ec;
  out = (resident - std::min(resident, shared)) * static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  return {};
}

std::error_code SystemdNotifier::open() noexcept {
  const char* socket_path = std::getenv("NOTIFY_SOCKET");
  if (socket_path == nullptr || socket_path[0] == '\0') return {};
  const std::size_t length = std::strlen(socket_path);
  if (length >= path_.size()) return make_error(ENAMETOOLONG);
  if (socket_path[0] != '/' && socket_path[0] != '@') return make_error(EAFNOSUPPORT);
  std::memcpy(path_.data(), socket_path, length);
  if (path_[0] == '@') path_[0] = '\0';  // abstract namespace
  path_length_ = length;
  if (const char* usec = std::getenv("WATCHDOG_USEC")) {
    const long long value = std::atoll(usec);
    if (value > 0) watchdog_interval_ = std::chrono::microseconds(value / 2);
  }
  int fd = -1;
  if (auto ec = sys_socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0, fd)) return ec;
  fd_ = UniqueFd(fd);
  return {};
}

std::error_code SystemdNotifier::notify(std::string_view message) noexcept {
  if (!fd_.valid()) return {};
  sockaddr_un address{};
  address.sun_family = AF_UNIX;
  std::memcpy(address.sun_path, path_.data(), path_length_);
  const auto address_length = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + path_length_);
  const ssize_t r = retry_eintr([&] {
    return ::sendto(fd_.get(), message.data(), message.size(), MSG_NOSIGNAL,
                    reinterpret_cast<const sockaddr*>(&address), address_length);
  });
  return r < 0 ? last_error() : std::error_code{};
}

}  // namespace markloop::platform
