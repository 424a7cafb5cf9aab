// Files the host tools (markloop-replay, -eval, -sim, -detect, -train) read
// and write. Every input is read whole through platform::read_file_bounded,
// up to a limit that suits what it holds, and parsed from memory; every
// output is checked up to its close. Errors read "PATH: what went wrong".
//
// Exit statuses, the same in every tool: 0 success; 1 a failure while
// running (an output that could not be written: fail_run); 2 a bad command
// line, configuration or input (cli::fail).
#pragma once

#include <cerrno>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>
#include <system_error>

#include "app/common/cli.hpp"
#include "app/common/result.hpp"
#include "platform/files.hpp"

namespace markloop::tools {

// `path` whole when it holds at most `max_bytes`; else "PATH: why". `what`
// names the kind of file for the messages on a directory or a file over the
// limit ("a markings file").
inline Result<std::string> read_input(const std::string& path, std::size_t max_bytes, const char* what) {
  std::string text;
  if (const std::error_code ec = platform::read_file_bounded(path.c_str(), max_bytes, text))
    return error(platform::describe_read_error(path, ec, max_bytes, what));
  return text;
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

  Status open(const std::string& path) {
    path_ = path;
    errno = 0;
    file_ = std::fopen(path.c_str(), "w");
    if (file_ == nullptr) return error(write_error(path));
    return {};
  }
  std::FILE* get() const { return file_; }
  const std::string& path() const { return path_; }

  // Flushes and closes; the error when any write failed. errno is left as
  // the failed write set it, so that the reason is the first.
  Status close() {
    if (file_ == nullptr) return {};
    const bool flushed = std::fflush(file_) == 0;
    const bool clean = std::ferror(file_) == 0;
    const int reason = errno;
    const bool closed = std::fclose(file_) == 0;
    file_ = nullptr;
    if (flushed && clean && closed) return {};
    if (!flushed || !clean) errno = reason;
    return error(write_error(path_));
  }

 private:
  std::string path_;
  std::FILE* file_ = nullptr;
};

// `size` bytes at `data` as the whole of the file `path` (an image encoded
// in memory); else "PATH: cannot write: why".
inline Status write_whole_file(const std::string& path, const void* data, std::size_t size) {
  OutputFile file;
  if (Status opened = file.open(path); !opened) return opened;
  std::fwrite(data, 1, size, file.get());
  return file.close();
}

// Standard output flushed and checked (a full disk, a closed pipe).
inline Status flush_stdout() {
  if (std::fflush(stdout) == 0 && std::ferror(stdout) == 0) return {};
  return error(write_error("standard output"));
}

// A failure while running, such as an output that could not be written:
// "PROGRAM: message" and exit status 1.
[[noreturn]] inline void fail_run(const std::string& message) {
  // What was printed so far first, so that the message starts its own line
  // when both go to one file.
  std::fflush(stdout);
  std::fprintf(stderr, "%s: %s\n", cli::program_name(), message.c_str());
  std::exit(1);
}

}  // namespace markloop::tools
