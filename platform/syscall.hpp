// The one place where markloop calls into the kernel: every wrapper retries on
// EINTR and reports failure as a std::error_code (system_category, errno
// value). Nothing here throws and nothing logs; callers add context.
#pragma once

#include <sys/types.h>

#include <cerrno>

#include <chrono>
#include <cstddef>
#include <system_error>

struct msghdr;
struct pollfd;
struct sockaddr;

namespace markloop::platform {

// The errno of the last failed call as an error_code.
std::error_code last_error() noexcept;
inline std::error_code make_error(int errno_value) noexcept {
  return {errno_value, std::system_category()};
}

// Result of a call that transfers bytes: `bytes` is valid when !error.
struct IoResult {
  std::size_t bytes = 0;
  std::error_code error{};
};

std::error_code sys_socket(int domain, int type, int protocol, int& fd_out) noexcept;
std::error_code sys_bind(int fd, const sockaddr* addr, unsigned len) noexcept;
std::error_code sys_setsockopt(int fd, int level, int name, const void* value, unsigned len) noexcept;
std::error_code sys_ioctl(int fd, unsigned long request, void* arg) noexcept;
// open(2) of a path (device nodes); the new descriptor goes to fd_out.
std::error_code sys_open(const char* path, int flags, int& fd_out) noexcept;
// Shared read/write mapping of `length` bytes at `offset` (device buffers).
std::error_code sys_mmap_shared(int fd, std::size_t length, long offset, void*& out) noexcept;
void sys_munmap(void* address, std::size_t length) noexcept;
IoResult sys_recvmsg(int fd, msghdr* msg, int flags) noexcept;
IoResult sys_write(int fd, const void* data, std::size_t size) noexcept;
IoResult sys_read(int fd, void* data, std::size_t size) noexcept;

// poll() on an array; returns the number of ready descriptors in `ready`
// (0 on timeout). The remaining timeout is recomputed after EINTR.
std::error_code sys_poll(pollfd* fds, unsigned count, std::chrono::milliseconds timeout, int& ready) noexcept;

// True for the errno values that mean "try again later" on a non-blocking fd.
inline bool is_would_block(const std::error_code& ec) noexcept {
  return ec.category() == std::system_category() && (ec.value() == EAGAIN || ec.value() == EWOULDBLOCK);
}

}  // namespace markloop::platform
