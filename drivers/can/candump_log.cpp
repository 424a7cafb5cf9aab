#include "drivers/can/candump_log.hpp"

#include <fcntl.h>
#include <time.h>

#include <cerrno>
#include <cstring>
#include <limits>

#include "platform/os.hpp"
#include "platform/syscall.hpp"

namespace markloop::can {

namespace {

constexpr char kHex[] = "0123456789ABCDEF";

bool valid_interface(std::string_view name) {
  if (name.empty() || name.size() > kCandumpMaxInterface) return false;
  for (char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
                    c == '-' || c == '.' || c == '@';
    if (!ok) return false;
  }
  return true;
}

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

std::int64_t realtime_ns() {
  timespec ts{};
  ::clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace

std::size_t format_candump_line(const CanFrame& frame, std::string_view interface, char* out,
                                std::size_t capacity) noexcept {
  if (!frame.valid() || !valid_interface(interface) || frame.timestamp_ns < 0) return 0;
  const std::int64_t sec = frame.timestamp_ns / 1'000'000'000;
  const std::int64_t usec = (frame.timestamp_ns % 1'000'000'000) / 1000;
  char id[9];
  if (frame.extended)
    std::snprintf(id, sizeof(id), "%08X", static_cast<unsigned>(frame.id));
  else
    std::snprintf(id, sizeof(id), "%03X", static_cast<unsigned>(frame.id));
  char data[17];
  for (std::uint8_t i = 0; i < frame.dlc; ++i) {
    data[2 * i] = kHex[frame.data[i] >> 4];
    data[2 * i + 1] = kHex[frame.data[i] & 0xF];
  }
  data[2 * frame.dlc] = '\0';
  const int n = std::snprintf(out, capacity, "(%010lld.%06lld) %.*s %s#%s\n", static_cast<long long>(sec),
                              static_cast<long long>(usec), static_cast<int>(interface.size()),
                              interface.data(), id, data);
  if (n <= 0 || static_cast<std::size_t>(n) >= capacity) return 0;
  return static_cast<std::size_t>(n);
}

namespace {

// Where parsing one line has got to; fail() records the first error.
struct LineCursor {
  std::string_view line;
  std::size_t pos = 0;
  CandumpLineError& error;

  bool fail(std::size_t at, const char* what) {
    error.column = at + 1;
    error.what = what;
    return false;
  }
  bool at_end() const { return pos >= line.size(); }
  bool digit() const { return !at_end() && line[pos] >= '0' && line[pos] <= '9'; }
  bool expect(char c, const char* what) {
    if (at_end() || line[pos] != c) return fail(pos, what);
    ++pos;
    return true;
  }
};

// "(SECONDS.UUUUUU) " into nanoseconds.
bool parse_timestamp(LineCursor& in, std::int64_t& ns) {
  if (!in.expect('(', "expected '(' starting the timestamp")) return false;
  // Seconds: 1..10 digits, at most what nanoseconds in 64 bits hold (the
  // year 2262): a timestamp beyond would overflow, not merely be wrong.
  constexpr std::int64_t kMaxSeconds = std::numeric_limits<std::int64_t>::max() / 1'000'000'000 - 1;
  std::int64_t sec = 0;
  const std::size_t sec_start = in.pos;
  while (in.digit()) {
    if (in.pos - sec_start >= 10) return in.fail(in.pos, "timestamp seconds too long");
    sec = sec * 10 + (in.line[in.pos] - '0');
    ++in.pos;
  }
  if (in.pos == sec_start) return in.fail(in.pos, "expected timestamp seconds (digits)");
  if (sec > kMaxSeconds) return in.fail(sec_start, "timestamp seconds beyond the year 2262");
  if (!in.expect('.', "expected '.' in the timestamp")) return false;
  std::int64_t usec = 0;
  for (int i = 0; i < 6; ++i, ++in.pos) {
    if (!in.digit()) return in.fail(in.pos, "timestamp needs exactly 6 digits of microseconds");
    usec = usec * 10 + (in.line[in.pos] - '0');
  }
  if (!in.expect(')', "expected ')' after 6 digits of microseconds")) return false;
  if (!in.expect(' ', "expected one space after ')'")) return false;
  ns = sec * 1'000'000'000 + usec * 1000;
  return true;
}

// "INTERFACE " (the space consumed).
bool parse_interface(LineCursor& in, std::string_view& iface) {
  const std::size_t if_start = in.pos;
  while (!in.at_end() && in.line[in.pos] != ' ') ++in.pos;
  iface = in.line.substr(if_start, in.pos - if_start);
  if (iface.empty()) return in.fail(if_start, "missing interface name");
  if (!valid_interface(iface)) return in.fail(if_start, "bad interface name (1..15 of [A-Za-z0-9_.@-])");
  if (in.at_end()) return in.fail(in.pos, "expected ' ID#DATA' after the interface name");
  ++in.pos;  // the space
  return true;
}

// "ID#" (the '#' consumed): 3 hex digits standard, 8 extended.
bool parse_id(LineCursor& in, std::uint32_t& id, bool& extended) {
  const std::size_t id_start = in.pos;
  id = 0;
  while (!in.at_end() && in.line[in.pos] != '#') {
    const int v = hex_value(in.line[in.pos]);
    if (v < 0) return in.fail(in.pos, "bad character in the CAN id (hex digits expected)");
    if (in.pos - id_start >= 8) return in.fail(in.pos, "CAN id longer than 8 hex digits");
    id = (id << 4) | static_cast<std::uint32_t>(v);
    ++in.pos;
  }
  const std::size_t id_len = in.pos - id_start;
  if (in.at_end()) return in.fail(in.pos, "missing '#' after the CAN id");
  extended = false;
  if (id_len == 3) {
    if (id > CanFrame::kMaxStandardId) return in.fail(id_start, "standard CAN id above 0x7FF");
  } else if (id_len == 8) {
    if (id & 0x20000000U) return in.fail(id_start, "error frames are not supported");
    if (id > CanFrame::kMaxExtendedId) return in.fail(id_start, "extended CAN id above 0x1FFFFFFF");
    extended = true;
  } else {
    return in.fail(id_start, "CAN id must have 3 (standard) or 8 (extended) hex digits");
  }
  ++in.pos;  // '#'
  return true;
}

// Up to 8 data bytes as hex pairs, then at most a direction mark.
bool parse_data(LineCursor& in, std::array<std::uint8_t, 8>& data, std::uint8_t& dlc) {
  const std::string_view line = in.line;
  std::size_t& pos = in.pos;
  if (pos < line.size() && line[pos] == '#') return in.fail(pos, "CAN FD frames are not supported");
  if (pos < line.size() && (line[pos] == 'R' || line[pos] == 'r'))
    return in.fail(pos, "remote (RTR) frames are not supported");
  dlc = 0;
  while (pos < line.size() && line[pos] != ' ') {
    const int hi = hex_value(line[pos]);
    if (hi < 0) return in.fail(pos, "bad character in the data (hex digits expected)");
    if (pos + 1 >= line.size() || line[pos + 1] == ' ')
      return in.fail(pos, "odd number of hex digits in the data");
    const int lo = hex_value(line[pos + 1]);
    if (lo < 0) return in.fail(pos + 1, "bad character in the data (hex digits expected)");
    if (dlc == CanFrame::kMaxDlc) return in.fail(pos, "more than 8 data bytes");
    data[dlc++] = static_cast<std::uint8_t>((hi << 4) | lo);
    pos += 2;
  }
  if (pos < line.size()) {
    // candump may mark the direction of a frame with a trailing " R" or " T".
    const std::string_view rest = line.substr(pos);
    if (rest != " R" && rest != " T") return in.fail(pos, "unexpected text after the data");
  }
  return true;
}

}  // namespace

bool parse_candump_line(std::string_view line, CandumpRecord& out, CandumpLineError& error) noexcept {
  out = CandumpRecord{};
  LineCursor in{line, 0, error};
  if (line.empty()) return in.fail(0, "empty line");
  std::int64_t timestamp_ns = 0;
  std::string_view iface;
  std::uint32_t id = 0;
  bool extended = false;
  std::uint8_t dlc = 0;
  if (!parse_timestamp(in, timestamp_ns) || !parse_interface(in, iface) || !parse_id(in, id, extended) ||
      !parse_data(in, out.frame.data, dlc))
    return false;
  out.frame.id = id;
  out.frame.extended = extended;
  out.frame.dlc = dlc;
  out.frame.timestamp_ns = timestamp_ns;
  std::memcpy(out.interface.data(), iface.data(), iface.size());
  out.interface[iface.size()] = '\0';
  return true;
}

// ---------------------------------------------------------------- writer

std::error_code CandumpLogWriter::open(const char* path, std::string_view interface, bool append) noexcept {
  (void)close();
  if (path == nullptr || !valid_interface(interface))
    return std::make_error_code(std::errc::invalid_argument);
  const int flags = O_WRONLY | O_CREAT | (append ? O_APPEND : O_TRUNC);
  int fd = -1;
  if (const std::error_code ec = platform::sys_open_mode(path, flags, 0644, fd)) return ec;
  fd_.reset(fd);
  interface_.fill('\0');
  std::memcpy(interface_.data(), interface.data(), interface.size());
  used_ = 0;
  return {};
}

std::error_code CandumpLogWriter::send(const CanFrame& frame) noexcept {
  if (!fd_) return std::make_error_code(std::errc::not_connected);
  if (!frame.valid()) return std::make_error_code(std::errc::invalid_argument);
  CanFrame stamped = frame;
  if (stamped.timestamp_ns == 0) stamped.timestamp_ns = realtime_ns();
  if (buffer_.size() - used_ < kCandumpMaxLine) {
    if (auto ec = flush()) return ec;
  }
  const std::size_t n = format_candump_line(stamped, std::string_view(interface_.data()),
                                            buffer_.data() + used_, buffer_.size() - used_);
  if (n == 0) return std::make_error_code(std::errc::invalid_argument);
  used_ += n;
  ++frames_;
  return {};
}

std::error_code CandumpLogWriter::flush() noexcept {
  std::size_t done = 0;
  while (done < used_) {
    const platform::IoResult r = platform::sys_write(fd_.get(), buffer_.data() + done, used_ - done);
    if (r.error) {
      ++write_errors_;
      // Keep what was not written for the next attempt.
      std::memmove(buffer_.data(), buffer_.data() + done, used_ - done);
      used_ -= done;
      return r.error;
    }
    done += r.bytes;
  }
  used_ = 0;
  return {};
}

std::error_code CandumpLogWriter::close() noexcept {
  if (!fd_) return {};
  std::error_code ec = flush();
  fd_.reset();
  used_ = 0;
  return ec;
}

// ---------------------------------------------------------------- reader

std::error_code CandumpLogReader::open(const std::string& path) noexcept {
  close();
  if (auto ec = stream_.open(path.c_str())) return ec;
  path_ = path;
  line_ = 0;
  failed_ = false;
  error_.clear();
  return {};
}

void CandumpLogReader::close() noexcept {
  stream_.close();
}

CandumpLogReader::Status CandumpLogReader::next(CandumpRecord& out) {
  if (failed_) return Status::Error;
  if (!stream_.is_open()) {
    failed_ = true;
    error_ = path_ + ": not open";
    return Status::Error;
  }
  line_text_.clear();
  char c = 0;
  platform::InputStream::Status read = platform::InputStream::Status::kOk;
  while ((read = stream_.get(c)) == platform::InputStream::Status::kOk) {
    if (c == '\n') break;
    line_text_.push_back(c);
    if (line_text_.size() > kMaxLine) break;
  }
  if (read == platform::InputStream::Status::kStopped) return Status::Stopped;
  if (read == platform::InputStream::Status::kError) {
    failed_ = true;
    error_ = path_ + ":" + std::to_string(line_ + 1) + ": read error: " + stream_.error().message();
    return Status::Error;
  }
  if (read == platform::InputStream::Status::kEnd && line_text_.empty()) return Status::End;
  ++line_;
  CandumpLineError err;
  if (line_text_.size() > kMaxLine) {
    err = {kMaxLine + 1, "line too long"};
    line_text_.resize(kMaxLine);
  } else if (parse_candump_line(line_text_, out, err)) {
    return Status::Frame;
  }
  failed_ = true;
  error_ = path_ + ":" + std::to_string(line_) + ":" + std::to_string(err.column) + ": " + err.what +
           " in '" + line_text_ + "'";
  return Status::Error;
}

}  // namespace markloop::can
