// can-utils `candump -l` log files: a CanFrameSink that writes them and a
// strict reader (used to feed recorded traffic, e.g. odometry, to the ECU).
//
// Line format (one frame per line, exactly what candump -l writes):
//   (1700000000.123456) vcan0 123#DEADBEEF
//   (1700000000.123457) vcan0 18FF0001#0102
// Standard ids are 3 hex digits, extended ids 8; data is 0..8 bytes as pairs
// of uppercase hex digits. Remote, error and CAN FD frames are not supported.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>
#include <system_error>

#include "drivers/can/can_frame.hpp"
#include "platform/files.hpp"
#include "platform/unique_fd.hpp"

namespace markloop::can {

// Longest line format_candump_line() can produce, newline included.
inline constexpr std::size_t kCandumpMaxLine = 64;
inline constexpr std::size_t kCandumpMaxInterface = 15;  // IFNAMSIZ - 1

// Writes one log line (with '\n') for `frame` on `interface` into `out`.
// Returns the number of characters, or 0 when the frame is invalid, the
// interface name is empty/too long, or `out` is too small.
std::size_t format_candump_line(const CanFrame& frame, std::string_view interface, char* out,
                                std::size_t capacity) noexcept;

struct CandumpRecord {
  CanFrame frame;
  std::array<char, kCandumpMaxInterface + 1> interface {};  // NUL-terminated
  std::string_view interface_name() const { return {interface.data()}; }
};

// What is wrong with a line: 1-based column and a fixed description.
struct CandumpLineError {
  std::size_t column = 0;
  const char* what = nullptr;
};

// Parses one line (without its newline). Returns true and fills `out`, or
// false and fills `error`.
bool parse_candump_line(std::string_view line, CandumpRecord& out, CandumpLineError& error) noexcept;

// A sink writing candump log lines to a file. The output is buffered in a
// fixed buffer and written by flush(), when the buffer is full, and by
// close()/the destructor. Frames without a timestamp get the current time.
class CandumpLogWriter final : public CanFrameSink {
 public:
  CandumpLogWriter() = default;
  ~CandumpLogWriter() override { (void)close(); }
  CandumpLogWriter(const CandumpLogWriter&) = delete;
  CandumpLogWriter& operator=(const CandumpLogWriter&) = delete;

  // Creates/truncates `path` (or appends). `interface` is written on every line.
  std::error_code open(const char* path, std::string_view interface, bool append = false) noexcept;
  // Flushes and closes; safe to call twice.
  std::error_code close() noexcept;
  bool is_open() const noexcept { return fd_.valid(); }

  std::error_code send(const CanFrame& frame) noexcept override;
  std::error_code flush() noexcept;

  std::uint64_t frames_written() const noexcept { return frames_; }
  std::uint64_t write_errors() const noexcept { return write_errors_; }

 private:
  platform::UniqueFd fd_;
  std::array<char, kCandumpMaxInterface + 1> interface_{};
  std::array<char, 4096> buffer_{};
  std::size_t used_ = 0;
  std::uint64_t frames_ = 0;
  std::uint64_t write_errors_ = 0;
};

// Reads a candump log (a file or a pipe) one frame at a time. Not for the
// real-time loop (it uses std::string for the line and the error message).
class CandumpLogReader {
 public:
  // Stopped: the stop fd became readable while waiting for a pipe's data.
  enum class Status { Frame, End, Error, Stopped };

  CandumpLogReader() = default;
  ~CandumpLogReader() { close(); }
  CandumpLogReader(const CandumpLogReader&) = delete;
  CandumpLogReader& operator=(const CandumpLogReader&) = delete;

  // Directories are refused (EISDIR).
  std::error_code open(const std::string& path) noexcept;
  void close() noexcept;
  // Waits for a pipe's data also end when `stop_fd` (a signalfd) is readable.
  void set_stop_fd(int stop_fd) noexcept { stream_.set_stop_fd(stop_fd); }

  // Frame: `out` holds the next frame. End: no more lines. Error: error()
  // says "file:line:column: what (line text)"; further calls return Error.
  Status next(CandumpRecord& out);
  const std::string& error() const { return error_; }
  std::size_t line_number() const { return line_; }
  const std::string& path() const { return path_; }

 private:
  platform::InputStream stream_;
  std::string path_;
  // Longer lines are no candump line (the longest is kCandumpMaxLine).
  static constexpr std::size_t kMaxLine = 256;
  std::string line_text_;
  std::string error_;
  std::size_t line_ = 0;
  bool failed_ = false;
};

}  // namespace markloop::can
