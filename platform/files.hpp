// Files read and written without trusting them: inputs read whole only up to
// a limit, streams whose waits end on a stop request, maps replaced
// atomically under a lock. As in syscall.hpp: EINTR retried, failures as
// std::error_code, no throw, no log; callers add the path and what it is.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>

#include "platform/unique_fd.hpp"

namespace markloop::platform {

// The whole file at `path` into `out`. A directory fails with EISDIR; a file
// larger than `max_bytes` fails with EFBIG before it is read (regular files)
// or once `max_bytes` + 1 bytes have arrived (pipes, devices such as
// /dev/zero), so that no input can make the reader grow without bound. A
// FIFO waits for its writer, as `cat` would.
std::error_code read_file_bounded(const char* path, std::size_t max_bytes, std::string& out);

// ESPIPE when `path` is a FIFO or socket: for a file that is read more than
// once, whose second reader would wait for a writer that has gone.
std::error_code refuse_pipe(const char* path) noexcept;

// "PATH: what is wrong" for an error of read_file_bounded() or InputStream,
// naming the limit for EFBIG ("larger than 1 MiB, the limit for a WHAT").
std::string describe_read_error(const std::string& path, std::error_code ec, std::size_t max_bytes,
                                const char* what);

// A file, pipe or FIFO read in order through a fixed buffer (no heap after
// open). Opened blocking, so that a FIFO waits for its writer as `cat`
// would; then switched to non-blocking, and every wait for data is a poll()
// on the stream and on `stop_fd` (the signalfd): a stop request ends the
// wait at once, whatever the writer does. Directories are refused (EISDIR).
class InputStream {
 public:
  enum class Status : std::uint8_t { kOk, kEnd, kStopped, kError };

  InputStream() = default;
  InputStream(InputStream&&) noexcept = default;
  InputStream& operator=(InputStream&&) noexcept = default;

  std::error_code open(const char* path) noexcept;
  void close() noexcept;
  bool is_open() const noexcept { return fd_.valid(); }
  // -1: waits are ended by nothing but data, end of file or an error.
  void set_stop_fd(int stop_fd) noexcept { stop_fd_ = stop_fd; }

  // Exactly `size` bytes into `data` (nullptr: skipped), unless the stream
  // ends (kEnd, `got` says how many arrived), the stop fd becomes readable
  // (kStopped) or reading fails (kError, error()).
  Status read(void* data, std::size_t size, std::size_t& got) noexcept;
  // One byte.
  Status get(char& c) noexcept;
  std::error_code error() const noexcept { return error_; }
  // Bytes consumed so far.
  std::uint64_t offset() const noexcept { return offset_; }

 private:
  Status fill() noexcept;

  UniqueFd fd_;
  int stop_fd_ = -1;
  std::array<std::uint8_t, 1 << 16> buffer_{};
  std::size_t begin_ = 0;
  std::size_t end_ = 0;
  std::uint64_t offset_ = 0;
  std::error_code error_{};
};

// Writes `content` as the file at `path` without ever leaving a partial
// file: a regular file (or a new one) is written to a unique temporary in
// the same directory, fsynced and renamed over it. An existing device or
// FIFO (/dev/stdout) is written to directly, as a shell redirection would;
// a directory fails with EISDIR.
std::error_code write_file_replacing(const char* path, std::string_view content);

// rename(2) that never replaces an existing file (EEXIST instead).
std::error_code rename_no_replace(const char* from, const char* to) noexcept;

// Creates a new file from `path_template`, whose last six characters are
// "XXXXXX" and are replaced in place to make a name no other file has.
std::error_code create_unique_file(char* path_template, unsigned mode, int& fd_out) noexcept;

// An exclusive advisory lock (flock) on `fd`, without waiting: EWOULDBLOCK
// when another process holds it.
std::error_code try_lock_exclusive(int fd) noexcept;

// Memory the system could give this process now (MemAvailable), or its
// physical memory when the kernel does not say.
std::uint64_t available_memory_bytes() noexcept;

// A regular file's identity (device and inode), to tell that an output would
// overwrite an input under another name; none for anything else.
struct FileId {
  std::uint64_t device = 0;
  std::uint64_t inode = 0;
  bool operator==(const FileId&) const = default;
};

std::optional<FileId> regular_file_id(const std::string& path);

// Whether writing `output` would overwrite the input file `input`.
bool overwrites(const std::string& output, const std::string& input);

}  // namespace markloop::platform
