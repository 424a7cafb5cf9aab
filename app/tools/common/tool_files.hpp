// Files the host tools (markloop-replay, -eval, -sim, -detect, -train) read
// and write. Every input is read whole through platform::read_file_bounded,
// up to a limit that suits what it holds, and parsed from memory; every
// output is checked up to its close. Errors read "PATH: what went wrong".
//
// Exit statuses, the same in every tool: 0 success; 1 a failure while
// running (an output that could not be written: fail_run); 2 a bad command
// line, configuration or input (cli::fail).
#pragma once

#include <sys/stat.h>

#include <cerrno>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>

#include "app/common/cli.hpp"
#include "platform/files.hpp"

namespace markloop::tools {

// `path` whole into `text` when it holds at most `max_bytes`; else false with
// "PATH: why" in `error`. `what` names the kind of file for the messages on
// a directory or a file over the limit ("a markings file").
inline bool read_input(const std::string& path, std::size_t max_bytes, const char* what, std::string& text,
                       std::string& error) {
  const std::error_code ec = platform::read_file_bounded(path.c_str(), max_bytes, text);
  if (ec) error = platform::describe_read_error(path, ec, max_bytes, what);
  return !ec;
}

// The lines of a text held in memory, numbered from 1, each without its
// line end ("\n" or "\r\n"). A last line without a newline counts.
class Lines {
 public:
  explicit Lines(std::string_view text) : rest_(text) {}

  // The next line; false after the last.
  bool next(std::string_view& line) {
    if (rest_.empty()) return false;
    const std::size_t end = rest_.find('\n');
    line = rest_.substr(0, end);
    rest_ = end == std::string_view::npos ? std::string_view() : rest_.substr(end + 1);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    ++number_;
    return true;
  }
  // The number of the line next() returned last.
  std::size_t number() const { return number_; }

 private:
  std::string_view rest_;
  std::size_t number_ = 0;
};

// A regular file's identity (device and inode), to tell that an output would
// overwrite an input under another name; none for anything else.
struct FileId {
  dev_t device = 0;
  ino_t inode = 0;
  bool operator==(const FileId&) const = default;
};

inline std::optional<FileId> regular_file_id(const std::string& path) {
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0 || !S_ISREG(info.st_mode)) return std::nullopt;
  return FileId{info.st_dev, info.st_ino};
}

// Whether writing `output` would overwrite the input file `input`.
inline bool overwrites(const std::string& output, const std::string& input) {
  const auto out = regular_file_id(output);
  return out && out == regular_file_id(input);
}

// "PATH: cannot write: why", with errno's reason when there is one.
inline std::string write_error(const std::string& path) {
  return path + ": cannot write: " + (errno != 0 ? std::strerror(errno) : "write error");
}

// An output file written through stdio, checked up to its close: a full
// disk or a bad path is an error naming the file, never silently lost data.
class OutputFile {
 public:
  OutputFile() = default;
  ~OutputFile() {
    if (file_ != nullptr) std::fclose(file_);
  }
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  bool open(const std::string& path, std::string& error) {
    path_ = path;
    errno = 0;
    file_ = std::fopen(path.c_str(), "w");
    if (file_ == nullptr) error = write_error(path);
    return file_ != nullptr;
  }
  std::FILE* get() const { return file_; }
  const std::string& path() const { return path_; }

  // Flushes and closes; false with the error when any write failed. errno
  // is left as the failed write set it, so that the reason is the first.
  bool close(std::string& error) {
    if (file_ == nullptr) return true;
    const bool flushed = std::fflush(file_) == 0;
    const bool clean = std::ferror(file_) == 0;
    const int reason = errno;
    const bool closed = std::fclose(file_) == 0;
    file_ = nullptr;
    if (flushed && clean && closed) return true;
    if (!flushed || !clean) errno = reason;
    error = write_error(path_);
    return false;
  }

 private:
  std::string path_;
  std::FILE* file_ = nullptr;
};

// `size` bytes at `data` as the whole of the file `path` (an image encoded
// in memory); false with "PATH: cannot write: why".
inline bool write_whole_file(const std::string& path, const void* data, std::size_t size,
                             std::string& error) {
  OutputFile file;
  if (!file.open(path, error)) return false;
  std::fwrite(data, 1, size, file.get());
  return file.close(error);
}

// Standard output flushed and checked (a full disk, a closed pipe).
inline bool flush_stdout(std::string& error) {
  if (std::fflush(stdout) == 0 && std::ferror(stdout) == 0) return true;
  error = write_error("standard output");
  return false;
}

// A failure while running, such as an output that could not be written:
// "PROGRAM: message" and exit status 1.
[[noreturn]] inline void fail_run(const std::string& message) {
  std::fprintf(stderr, "%s: %s\n", cli::program_name(), message.c_str());
  std::exit(1);
}

}  // namespace markloop::tools
