#include "platform/syscall.hpp"
#include "platform/retry_eintr.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>

namespace markloop::platform {

namespace {

using detail::retry_eintr;

std::int64_t monotonic_ms() noexcept {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000 + ts.tv_nsec / 1000000;
}

IoResult io_result(ssize_t r) noexcept {
  if (r < 0) return {0, last_error()};
  return {static_cast<std::size_t>(r), {}};
}

}  // namespace

std::error_code last_error() noexcept {
  return make_error(errno);
}

std::error_code sys_socket(int domain, int type, int protocol, int& fd_out) noexcept {
  fd_out = retry_eintr([&] { return ::socket(domain, type, protocol); });
  return fd_out < 0 ? last_error() : std::error_code{};
}

std::error_code sys_bind(int fd, const sockaddr* addr, unsigned len) noexcept {
  const int r = retry_eintr([&] { return ::bind(fd, addr, len); });
  return r < 0 ? last_error() : std::error_code{};
}

std::error_code sys_setsockopt(int fd, int level, int name, const void* value, unsigned len) noexcept {
  const int r = retry_eintr([&] { return ::setsockopt(fd, level, name, value, len); });
  return r < 0 ? last_error() : std::error_code{};
}

std::error_code sys_ioctl(int fd, unsigned long request, void* arg) noexcept {
  const int r = retry_eintr([&] { return ::ioctl(fd, request, arg); });
  return r < 0 ? last_error() : std::error_code{};
}

std::error_code sys_open(const char* path, int flags, int& fd_out) noexcept {
  fd_out = retry_eintr([&] { return ::open(path, flags); });
  return fd_out < 0 ? last_error() : std::error_code{};
}

std::error_code sys_mmap_shared(int fd, std::size_t length, long offset, void*& out) noexcept {
  void* p = ::mmap(nullptr, length, PROT_READ | PROT_WRITE, MAP_SHARED, fd, offset);
  if (p == MAP_FAILED) {
    out = nullptr;
    return last_error();
  }
  out = p;
  return {};
}

void sys_munmap(void* address, std::size_t length) noexcept {
  if (address != nullptr) ::munmap(address, length);
}

IoResult sys_recvmsg(int fd, msghdr* msg, int flags) noexcept {
  return io_result(retry_eintr([&] { return ::recvmsg(fd, msg, flags); }));
}

IoResult sys_write(int fd, const void* data, std::size_t size) noexcept {
  return io_result(retry_eintr([&] { return ::write(fd, data, size); }));
}

IoResult sys_read(int fd, void* data, std::size_t size) noexcept {
  return io_result(retry_eintr([&] { return ::read(fd, data, size); }));
}

std::error_code sys_poll(pollfd* fds, unsigned count, std::chrono::milliseconds timeout,
                         int& ready) noexcept {
  const bool infinite = timeout.count() < 0;
  const std::int64_t deadline = monotonic_ms() + timeout.count();
  for (;;) {
    int wait_ms = -1;
    if (!infinite) {
      const std::int64_t left = deadline - monotonic_ms();
      wait_ms = left > 0 ? static_cast<int>(left) : 0;
    }
    const int r = ::poll(fds, count, wait_ms);
    if (r >= 0) {
      ready = r;
      return {};
    }
    if (errno != EINTR) {
      ready = 0;
      return last_error();
    }
  }
}

}  // namespace markloop::platform
