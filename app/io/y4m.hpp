// YUV4MPEG2 (.y4m) video files: the frame-file format shared by the
// simulator (writes) and the ECU's file mode (reads). A plain header line,
// then per frame a "FRAME" line and the raw planes; common video tools
// (ffmpeg, mpv, GStreamer) read it.
//
// The reader hands out the luma (Y) plane only: markloop works on grey
// frames. It accepts mono, 420 (all siting variants), 422 and 444 8-bit
// streams at 0.1 to 1000 frames a second, skips the chroma planes (reading
// them: a pipe cannot seek) and never allocates after open().
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <span>
#include <string>
#include <string_view>

#include "platform/files.hpp"

namespace markloop::io {

// Frame rates a camera file may declare: outside them, the time between
// frames (and all the ECU does in it, such as its Status cycles) would be
// absurd.
inline constexpr double kMinFps = 0.1;
inline constexpr double kMaxFps = 1000.0;

enum class Y4mChroma : std::uint8_t { kMono, k420, k422, k444 };

struct Y4mFormat {
  int width = 0;
  int height = 0;
  int fps_numerator = 10;
  int fps_denominator = 1;
  Y4mChroma chroma = Y4mChroma::kMono;

  std::size_t luma_bytes() const { return static_cast<std::size_t>(width) * height; }
  std::size_t chroma_bytes() const;  // both chroma planes together
  double frame_period_s() const { return double(fps_denominator) / fps_numerator; }
};

// kStopped: the stop fd became readable while waiting for a pipe's data.
enum class Y4mRead : std::uint8_t { kFrame, kEnd, kError, kStopped };

class Y4mReader {
 public:
  Y4mReader() = default;
  ~Y4mReader() { close(); }
  Y4mReader(const Y4mReader&) = delete;
  Y4mReader& operator=(const Y4mReader&) = delete;

  // Opens and parses the stream header. On failure, error() says why.
  bool open(const std::string& path);
  // ... and checks that the frames are width x height, a camera's (error():
  // "PATH: frames are WxH, the camera's WxH").
  bool open(const std::string& path, int width, int height);
  void close();
  // Waits for a pipe's data also end when `stop_fd` (a signalfd) is readable.
  void set_stop_fd(int stop_fd) { stream_.set_stop_fd(stop_fd); }

  const Y4mFormat& format() const { return format_; }
  // Frames read so far (the index of the next frame).
  std::uint64_t frames_read() const { return frames_read_; }

  // Reads the next frame's luma plane into `luma` (exactly luma_bytes()).
  // kEnd at a clean end of file; kError (with error()) on a damaged frame.
  Y4mRead read_frame(std::span<std::uint8_t> luma);

  // "PATH: what is wrong" (with the frame number for frame errors).
  const std::string& error() const { return error_; }

 private:
  bool fail(const std::string& what);
  bool parse_header(std::string_view header);
  bool parse_frame_rate(std::string_view value);
  platform::InputStream stream_;
  std::string path_;
  std::string error_;
  Y4mFormat format_;
  std::uint64_t frames_read_ = 0;
};

class Y4mWriter {
 public:
  Y4mWriter() = default;
  ~Y4mWriter() { (void)close(); }
  Y4mWriter(const Y4mWriter&) = delete;
  Y4mWriter& operator=(const Y4mWriter&) = delete;

  // Creates `path` and writes the header of a mono stream.
  bool open(const std::string& path, int width, int height, int fps_numerator, int fps_denominator = 1);
  bool write_frame(std::span<const std::uint8_t> luma);
  // Flushes and closes; false (with error()) if anything failed to write.
  bool close();

  const std::string& error() const { return error_; }

 private:
  std::FILE* file_ = nullptr;
  std::string path_;
  std::string error_;
  Y4mFormat format_;
};

}  // namespace markloop::io
