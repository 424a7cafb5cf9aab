#include "app/io/y4m.hpp"

#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <string_view>

namespace markloop::io {
namespace {

constexpr std::string_view kMagic = "YUV4MPEG2";
constexpr std::string_view kFrameTag = "FRAME";
// Header and FRAME lines are short; a longer one means a damaged file.
constexpr std::size_t kMaxLine = 1024;
constexpr int kMaxDimension = 16384;

enum class LineRead : std::uint8_t { kLine, kEnd, kTooLong, kTruncated, kStopped, kError };

// Reads one line (without '\n') into buf.
LineRead read_line(platform::InputStream& in, char* buf, std::size_t capacity, std::size_t& length) {
  length = 0;
  for (;;) {
    char c = 0;
    switch (in.get(c)) {
      case platform::InputStream::Status::kOk:
        break;
      case platform::InputStream::Status::kEnd:
        return length == 0 ? LineRead::kEnd : LineRead::kTruncated;
      case platform::InputStream::Status::kStopped:
        return LineRead::kStopped;
      case platform::InputStream::Status::kError:
        return LineRead::kError;
    }
    if (c == '\n') return LineRead::kLine;
    if (length + 1 >= capacity) return LineRead::kTooLong;
    buf[length++] = c;
  }
}

bool parse_int(std::string_view text, int& out) {
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
  return ec == std::errc() && end == text.data() + text.size();
}

}  // namespace

std::size_t Y4mFormat::chroma_bytes() const {
  const std::size_t w = static_cast<std::size_t>(width), h = static_cast<std::size_t>(height);
  switch (chroma) {
    case Y4mChroma::kMono:
      return 0;
    case Y4mChroma::k420:
      return 2 * ((w + 1) / 2) * ((h + 1) / 2);
    case Y4mChroma::k422:
      return 2 * ((w + 1) / 2) * h;
    case Y4mChroma::k444:
      return 2 * w * h;
  }
  return 0;
}

bool Y4mReader::fail(const std::string& what) {
  error_ = path_ + ": " + what;
  return false;
}

bool Y4mReader::open(const std::string& path, int width, int height) {
  if (!open(path)) return false;
  if (format_.width == width && format_.height == height) return true;
  const std::string sizes = "frames are " + std::to_string(format_.width) + "x" +
                            std::to_string(format_.height) + ", the camera's " + std::to_string(width) + "x" +
                            std::to_string(height);
  close();
  return fail(sizes);
}

bool Y4mReader::open(const std::string& path) {
  close();
  path_ = path;
  error_.clear();
  frames_read_ = 0;
  format_ = {};
  if (auto ec = stream_.open(path.c_str()))
    return fail(ec.value() == EISDIR ? "is a directory, not a YUV4MPEG2 stream"
                                     : "cannot open: " + ec.message());

  char line[kMaxLine];
  std::size_t length = 0;
  switch (read_line(stream_, line, sizeof line, length)) {
    case LineRead::kLine:
      break;
    case LineRead::kEnd:
      return fail("empty file, not a YUV4MPEG2 stream");
    case LineRead::kError:
      return fail("read error: " + stream_.error().message());
    default:
      return fail("header line missing or too long");
  }
  return parse_header(std::string_view(line, length));
}

bool Y4mReader::parse_header(std::string_view header) {
  if (header.substr(0, kMagic.size()) != kMagic ||
      (header.size() > kMagic.size() && header[kMagic.size()] != ' '))
    return fail("not a YUV4MPEG2 stream (header does not start with YUV4MPEG2)");
  header.remove_prefix(kMagic.size());

  bool have_width = false, have_height = false;
  while (!header.empty()) {
    while (!header.empty() && header.front() == ' ') header.remove_prefix(1);
    if (header.empty()) break;
    const std::size_t end = header.find(' ');
    const std::string_view token = header.substr(0, end);
    header.remove_prefix(end == std::string_view::npos ? header.size() : end);
    const char tag = token.front();
    const std::string_view value = token.substr(1);
    if (tag == 'W') {
      if (!parse_int(value, format_.width) || format_.width <= 0 || format_.width > kMaxDimension)
        return fail("bad width '" + std::string(value) + "'");
      have_width = true;
    } else if (tag == 'H') {
      if (!parse_int(value, format_.height) || format_.height <= 0 || format_.height > kMaxDimension)
        return fail("bad height '" + std::string(value) + "'");
      have_height = true;
    } else if (tag == 'F') {
      if (!parse_frame_rate(value)) return false;
    } else if (tag == 'C') {
      if (value == "mono")
        format_.chroma = Y4mChroma::kMono;
      else if (value == "420" || value == "420jpeg" || value == "420mpeg2" || value == "420paldv")
        format_.chroma = Y4mChroma::k420;
      else if (value == "422")
        format_.chroma = Y4mChroma::k422;
      else if (value == "444")
        format_.chroma = Y4mChroma::k444;
      else
        return fail("unsupported colour space '" + std::string(value) + "' (8-bit mono, 420, 422, 444 only)");
    } else if (tag == 'I') {
      if (value != "p" && value != "?") return fail("interlaced streams are not supported");
    }
    // A (aspect) and X (extensions) do not matter here.
  }
  if (!have_width || !have_height) return fail("header lacks W or H");
  return true;
}

bool Y4mReader::parse_frame_rate(std::string_view value) {
  const std::size_t colon = value.find(':');
  if (colon == std::string_view::npos || !parse_int(value.substr(0, colon), format_.fps_numerator) ||
      !parse_int(value.substr(colon + 1), format_.fps_denominator) || format_.fps_numerator <= 0 ||
      format_.fps_denominator <= 0)
    return fail("bad frame rate '" + std::string(value) + "'");
  const double fps = double(format_.fps_numerator) / format_.fps_denominator;
  if (fps < kMinFps || fps > kMaxFps) {
    char text[160];
    std::snprintf(text, sizeof text, "frame rate %.*s (%g frames a second) is outside %g to %g",
                  static_cast<int>(value.size()), value.data(), fps, kMinFps, kMaxFps);
    return fail(text);
  }
  return true;
}

void Y4mReader::close() {
  stream_.close();
}

Y4mRead Y4mReader::read_frame(std::span<std::uint8_t> luma) {
  if (!stream_.is_open()) {
    error_ = path_ + ": not open";
    return Y4mRead::kError;
  }
  const auto frame_error = [&](const std::string& what) {
    error_ = path_ + ": frame " + std::to_string(frames_read_) + ": " + what;
    return Y4mRead::kError;
  };
  if (luma.size() != format_.luma_bytes()) return frame_error("destination has the wrong size");
  char line[kMaxLine];
  std::size_t length = 0;
  switch (read_line(stream_, line, sizeof line, length)) {
    case LineRead::kLine:
      break;
    case LineRead::kEnd:
      return Y4mRead::kEnd;
    case LineRead::kStopped:
      return Y4mRead::kStopped;
    case LineRead::kError:
      return frame_error("read error: " + stream_.error().message());
    default:
      return frame_error("FRAME line missing, truncated or too long");
  }
  const std::string_view tag(line, length);
  if (tag.substr(0, kFrameTag.size()) != kFrameTag ||
      (tag.size() > kFrameTag.size() && tag[kFrameTag.size()] != ' '))
    return frame_error("expected a FRAME line");
  const auto read_plane = [&](std::uint8_t* data, std::size_t size, const char* truncated) {
    std::size_t got = 0;
    switch (stream_.read(data, size, got)) {
      case platform::InputStream::Status::kOk:
        return Y4mRead::kFrame;
      case platform::InputStream::Status::kEnd:
        return frame_error(truncated);
      case platform::InputStream::Status::kStopped:
        return Y4mRead::kStopped;
      case platform::InputStream::Status::kError:
        break;
    }
    return frame_error("read error: " + stream_.error().message());
  };
  if (const Y4mRead r = read_plane(luma.data(), luma.size(), "truncated (luma plane incomplete)");
      r != Y4mRead::kFrame)
    return r;
  if (const Y4mRead r = read_plane(nullptr, format_.chroma_bytes(), "truncated (chroma planes incomplete)");
      r != Y4mRead::kFrame)
    return r;
  ++frames_read_;
  return Y4mRead::kFrame;
}

bool Y4mWriter::open(const std::string& path, int width, int height, int fps_numerator, int fps_denominator) {
  (void)close();
  path_ = path;
  error_.clear();
  if (width <= 0 || height <= 0 || width > kMaxDimension || height > kMaxDimension || fps_numerator <= 0 ||
      fps_denominator <= 0) {
    error_ = path + ": invalid size or frame rate";
    return false;
  }
  format_ = {width, height, fps_numerator, fps_denominator, Y4mChroma::kMono};
  file_ = std::fopen(path.c_str(), "wb");
  if (!file_) {
    error_ = path + ": " + std::strerror(errno);
    return false;
  }
  if (std::fprintf(file_, "YUV4MPEG2 W%d H%d F%d:%d Ip A1:1 Cmono\n", width, height, fps_numerator,
                   fps_denominator) < 0) {
    error_ = path + ": " + std::strerror(errno);
    return false;
  }
  return true;
}

bool Y4mWriter::write_frame(std::span<const std::uint8_t> luma) {
  if (!file_) {
    if (error_.empty()) error_ = path_ + ": not open";
    return false;
  }
  if (luma.size() != format_.luma_bytes()) {
    error_ = path_ + ": frame has the wrong size";
    return false;
  }
  if (std::fputs("FRAME\n", file_) < 0 || std::fwrite(luma.data(), 1, luma.size(), file_) != luma.size()) {
    error_ = path_ + ": " + std::strerror(errno);
    return false;
  }
  return true;
}

bool Y4mWriter::close() {
  if (!file_) return error_.empty();
  const bool ok = std::fflush(file_) == 0 && !std::ferror(file_);
  if (!ok && error_.empty()) error_ = path_ + ": " + std::strerror(errno);
  std::fclose(file_);
  file_ = nullptr;
  return ok && error_.empty();
}

}  // namespace markloop::io
