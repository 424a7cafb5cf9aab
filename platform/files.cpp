#include "platform/files.hpp"

#include <fcntl.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/sysinfo.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>

#include "platform/os.hpp"
#include "platform/retry_eintr.hpp"
#include "platform/syscall.hpp"

namespace markloop::platform {

namespace {

using detail::retry_eintr;

std::error_code open_not_directory(const char* path, UniqueFd& out) noexcept {
  int fd = -1;
  if (auto ec = sys_open_mode(path, O_RDONLY, 0, fd)) return ec;
  out.reset(fd);
  struct stat info {};
  if (::fstat(fd, &info) != 0) return last_error();
  if (S_ISDIR(info.st_mode)) return make_error(EISDIR);
  return {};
}

std::string size_text(std::size_t bytes) {
  if (bytes >= (std::size_t{1} << 20) && bytes % (std::size_t{1} << 20) == 0)
    return std::to_string(bytes >> 20) + " MiB";
  if (bytes >= 1024 && bytes % 1024 == 0) return std::to_string(bytes >> 10) + " KiB";
  return std::to_string(bytes) + " bytes";
}

}  // namespace

std::error_code read_file_bounded(const char* path, std::size_t max_bytes, std::string& out) {
  out.clear();
  UniqueFd file;
  if (auto ec = open_not_directory(path, file)) return ec;
  struct stat info {};
  if (::fstat(file.get(), &info) != 0) return last_error();
  if (S_ISREG(info.st_mode) && static_cast<std::uint64_t>(info.st_size) > max_bytes) return make_error(EFBIG);
  std::array<char, 1 << 14> chunk{};
  for (;;) {
    const IoResult r = sys_read(file.get(), chunk.data(), chunk.size());
    if (r.error) return r.error;
    if (r.bytes == 0) return {};
    if (out.size() + r.bytes > max_bytes) {
      out.clear();
      return make_error(EFBIG);
    }
    out.append(chunk.data(), r.bytes);
  }
}

std::error_code refuse_pipe(const char* path) noexcept {
  struct stat info {};
  if (::stat(path, &info) == 0 && (S_ISFIFO(info.st_mode) || S_ISSOCK(info.st_mode)))
    return make_error(ESPIPE);
  return {};
}

std::string describe_read_error(const std::string& path, std::error_code ec, std::size_t max_bytes,
                                const char* what) {
  if (ec.value() == EFBIG && ec.category() == std::system_category())
    return path + ": larger than " + size_text(max_bytes) + ", the limit for " + what;
  if (ec.value() == EISDIR && ec.category() == std::system_category())
    return path + ": is a directory, not " + what;
  if (ec.value() == ESPIPE && ec.category() == std::system_category())
    return path + ": is a pipe or socket, not " + what + " (it is read more than once: give a file)";
  if (ec.value() == EIO && ec.category() == std::system_category())
    return path + ": read error: " + ec.message();
  return path + ": cannot open: " + ec.message();
}

// ------------------------------------------------------------------ InputStream

std::error_code InputStream::open(const char* path) noexcept {
  close();
  if (auto ec = open_not_directory(path, fd_)) {
    fd_.reset();
    return ec;
  }
  const int flags = ::fcntl(fd_.get(), F_GETFL);
  if (flags < 0 || ::fcntl(fd_.get(), F_SETFL, flags | O_NONBLOCK) < 0) {
    const std::error_code ec = last_error();
    fd_.reset();
    return ec;
  }
  return {};
}

void InputStream::close() noexcept {
  fd_.reset();
  begin_ = end_ = 0;
  offset_ = 0;
  error_ = {};
}

InputStream::Status InputStream::fill() noexcept {
  if (!fd_) {
    error_ = make_error(EBADF);
    return Status::kError;
  }
  begin_ = end_ = 0;
  for (;;) {
    const IoResult r = sys_read(fd_.get(), buffer_.data(), buffer_.size());
    if (!r.error) {
      if (r.bytes == 0) return Status::kEnd;
      end_ = r.bytes;
      return Status::kOk;
    }
    if (!is_would_block(r.error)) {
      error_ = r.error;
      return Status::kError;
    }
    // No data yet (a pipe): wait for it or for a stop request, whichever
    // comes first. The stop fd is only looked at, never read: its owner
    // reads the signal.
    pollfd fds[2] = {{fd_.get(), POLLIN, 0}, {stop_fd_, POLLIN, 0}};
    int ready = 0;
    if (auto ec = sys_poll(fds, stop_fd_ >= 0 ? 2 : 1, std::chrono::milliseconds(-1), ready)) {
      error_ = ec;
      return Status::kError;
    }
    if (stop_fd_ >= 0 && (fds[1].revents & POLLIN) != 0) return Status::kStopped;
  }
}

InputStream::Status InputStream::read(void* data, std::size_t size, std::size_t& got) noexcept {
  auto* out = static_cast<std::uint8_t*>(data);
  got = 0;
  while (got < size) {
    if (begin_ == end_) {
      const Status s = fill();
      if (s != Status::kOk) return s;
    }
    const std::size_t n = std::min(size - got, end_ - begin_);
    if (out != nullptr) std::memcpy(out + got, buffer_.data() + begin_, n);
    begin_ += n;
    got += n;
    offset_ += n;
  }
  return Status::kOk;
}

InputStream::Status InputStream::get(char& c) noexcept {
  std::size_t got = 0;
  return read(&c, 1, got);
}

// ------------------------------------------------------------------ files

std::error_code write_file_replacing(const char* path, std::string_view content) {
  struct stat info {};
  const bool exists = ::stat(path, &info) == 0;
  if (exists && S_ISDIR(info.st_mode)) return make_error(EISDIR);
  if (exists && !S_ISREG(info.st_mode)) {
    int fd = -1;
    if (auto ec = sys_open_mode(path, O_WRONLY, 0, fd)) return ec;
    UniqueFd file(fd);
    return write_all(fd, content.data(), content.size());
  }
  std::string temporary = std::string(path) + ".tmp-XXXXXX";
  int fd = -1;
  if (auto ec = create_unique_file(temporary.data(), 0644, fd)) return ec;
  UniqueFd file(fd);
  std::error_code ec = write_all(fd, content.data(), content.size());
  if (!ec) ec = sys_fsync(fd);
  file.reset();
  if (!ec) ec = sys_rename(temporary.c_str(), path);
  if (ec) {
    (void)sys_unlink(temporary.c_str());
    return ec;
  }
  return sync_parent_directory(path);
}

std::error_code rename_no_replace(const char* from, const char* to) noexcept {
  const int r = retry_eintr([&] { return ::renameat2(AT_FDCWD, from, AT_FDCWD, to, RENAME_NOREPLACE); });
  if (r == 0) return {};
  const std::error_code ec = last_error();
  if (ec.value() != EINVAL && ec.value() != ENOSYS) return ec;
  // A file system without RENAME_NOREPLACE: link(2) fails on an existing name too.
  if (retry_eintr([&] { return ::link(from, to); }) != 0) return last_error();
  return sys_unlink(from);
}

std::error_code create_unique_file(char* path_template, unsigned mode, int& fd_out) noexcept {
  fd_out = retry_eintr([&] { return ::mkostemp(path_template, O_CLOEXEC); });
  if (fd_out < 0) return last_error();
  if (::fchmod(fd_out, static_cast<mode_t>(mode)) != 0) {
    const std::error_code ec = last_error();
    ::close(fd_out);
    (void)sys_unlink(path_template);
    fd_out = -1;
    return ec;
  }
  return {};
}

std::error_code try_lock_exclusive(int fd) noexcept {
  return retry_eintr([&] { return ::flock(fd, LOCK_EX | LOCK_NB); }) == 0 ? std::error_code{} : last_error();
}

std::uint64_t available_memory_bytes() noexcept {
  if (std::FILE* meminfo = std::fopen("/proc/meminfo", "re")) {
    char line[128];
    unsigned long long kib = 0;
    bool found = false;
    while (!found && std::fgets(line, sizeof line, meminfo) != nullptr)
      found = std::sscanf(line, "MemAvailable: %llu kB", &kib) == 1;
    std::fclose(meminfo);
    if (found) return std::uint64_t{kib} * 1024;
  }
  struct sysinfo info {};
  if (::sysinfo(&info) != 0) return 0;
  return std::uint64_t{info.totalram} * info.mem_unit;
}

std::optional<FileId> regular_file_id(const std::string& path) {
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0 || !S_ISREG(info.st_mode)) return std::nullopt;
  return FileId{static_cast<std::uint64_t>(info.st_dev), static_cast<std::uint64_t>(info.st_ino)};
}

bool overwrites(const std::string& output, const std::string& input) {
  const auto out = regular_file_id(output);
  return out && out == regular_file_id(input);
}

}  // namespace markloop::platform
