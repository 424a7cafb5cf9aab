#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <catch2/catch_test_macros.hpp>

#include "app/io/y4m.hpp"

using namespace markloop::io;

namespace {
std::string scratch(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / "markloop-y4m-tests";
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}
}  // namespace

TEST_CASE("Y4M: frames written are read back exactly") {
  const auto path = scratch("round.y4m");
  Y4mWriter writer;
  REQUIRE(writer.open(path, 6, 4, 30000, 1001));
  std::vector<std::uint8_t> frame(24);
  for (int f = 0; f < 3; ++f) {
    for (std::size_t i = 0; i < frame.size(); ++i) frame[i] = static_cast<std::uint8_t>(f * 50 + i);
    REQUIRE(writer.write_frame(frame));
  }
  REQUIRE(writer.close());

  Y4mReader reader;
  REQUIRE(reader.open(path));
  CHECK(reader.format().width == 6);
  CHECK(reader.format().height == 4);
  CHECK(reader.format().fps_numerator == 30000);
  CHECK(reader.format().fps_denominator == 1001);
  std::vector<std::uint8_t> luma(24);
  for (int f = 0; f < 3; ++f) {
    REQUIRE(reader.read_frame(luma) == Y4mRead::kFrame);
    CHECK(luma[5] == static_cast<std::uint8_t>(f * 50 + 5));
  }
  CHECK(reader.read_frame(luma) == Y4mRead::kEnd);
  CHECK(reader.frames_read() == 3);
}

TEST_CASE("Y4M: colour streams give their luma plane") {
  const auto path = scratch("c420.y4m");
  {
    std::ofstream out(path, std::ios::binary);
    out << "YUV4MPEG2 W4 H2 F25:1 C420jpeg\n";
    for (int f = 0; f < 2; ++f) {
      out << "FRAME\n";
      for (int i = 0; i < 8; ++i) out.put(static_cast<char>(10 * f + i));
      for (int i = 0; i < 4; ++i) out.put(static_cast<char>(128));  // U and V, 2x1 each
    }
  }
  Y4mReader reader;
  REQUIRE(reader.open(path));
  std::vector<std::uint8_t> luma(8);
  REQUIRE(reader.read_frame(luma) == Y4mRead::kFrame);
  REQUIRE(reader.read_frame(luma) == Y4mRead::kFrame);
  CHECK(luma[7] == 17);
  CHECK(reader.read_frame(luma) == Y4mRead::kEnd);
}

TEST_CASE("Y4M: damaged files are reported with the path and the frame") {
  Y4mReader reader;
  CHECK_FALSE(reader.open(scratch("does-not-exist.y4m")));
  CHECK(reader.error().find("does-not-exist.y4m") != std::string::npos);

  const auto not_y4m = scratch("not.y4m");
  std::ofstream(not_y4m) << "P5 4 4 255\n";
  CHECK_FALSE(reader.open(not_y4m));
  CHECK(reader.error().find("not a YUV4MPEG2") != std::string::npos);

  const auto bad_size = scratch("bad_size.y4m");
  std::ofstream(bad_size) << "YUV4MPEG2 W-4 H2 Cmono\n";
  CHECK_FALSE(reader.open(bad_size));
  CHECK(reader.error().find("bad width") != std::string::npos);

  const auto truncated = scratch("truncated.y4m");
  {
    std::ofstream out(truncated, std::ios::binary);
    out << "YUV4MPEG2 W4 H2 F10:1 Cmono\nFRAME\n01234567FRAME\n0123";
  }
  REQUIRE(reader.open(truncated));
  std::vector<std::uint8_t> luma(8);
  CHECK(reader.read_frame(luma) == Y4mRead::kFrame);
  CHECK(reader.read_frame(luma) == Y4mRead::kError);
  CHECK(reader.error().find("frame 1") != std::string::npos);
  CHECK(reader.error().find("truncated") != std::string::npos);
}

TEST_CASE("Y4M: a stream not of the camera's size is refused, with both sizes") {
  const auto path = scratch("sized.y4m");
  Y4mWriter writer;
  REQUIRE(writer.open(path, 6, 4, 10));
  REQUIRE(writer.write_frame(std::vector<std::uint8_t>(24, 7)));
  REQUIRE(writer.close());

  Y4mReader reader;
  CHECK(reader.open(path, 6, 4));
  std::vector<std::uint8_t> luma(24);
  CHECK(reader.read_frame(luma) == Y4mRead::kFrame);
  CHECK_FALSE(reader.open(path, 8, 4));
  CHECK(reader.error() == path + ": frames are 6x4, the camera's 8x4");
  CHECK(reader.read_frame(luma) == Y4mRead::kError);  // closed: nothing to read
  CHECK_FALSE(reader.open(scratch("none.y4m"), 6, 4));
  CHECK(reader.error().rfind(scratch("none.y4m") + ": ", 0) == 0);
}

TEST_CASE("Y4M: 4:2:0 streams are read through a pipe, and a stop request ends a stalled wait") {
  int fds[2];
  REQUIRE(::pipe(fds) == 0);
  const std::string header = "YUV4MPEG2 W4 H2 F10:1 C420jpeg\n";
  std::string frame = "FRAME\n" + std::string(8, 'Y') + std::string(4, 'c');  // luma, then 2x 2x1 chroma
  const std::string stream = header + frame + frame;
  REQUIRE(::write(fds[1], stream.data(), stream.size()) == static_cast<ssize_t>(stream.size()));
  int stop[2];
  REQUIRE(::pipe(stop) == 0);
  Y4mReader reader;
  REQUIRE(reader.open("/dev/fd/" + std::to_string(fds[0])));
  reader.set_stop_fd(stop[0]);
  std::vector<std::uint8_t> luma(8);
  CHECK(reader.read_frame(luma) == Y4mRead::kFrame);
  CHECK(reader.read_frame(luma) == Y4mRead::kFrame);
  CHECK(luma[0] == 'Y');
  // The writer is still there but sends nothing: only a stop ends the wait.
  REQUIRE(::write(stop[1], "x", 1) == 1);
  CHECK(reader.read_frame(luma) == Y4mRead::kStopped);
  ::close(fds[1]);
  ::close(stop[0]);
  ::close(stop[1]);
  reader.close();
  ::close(fds[0]);
}

TEST_CASE("Y4M: absurd frame rates and directories are refused with the reason") {
  const auto slow = scratch("slow.y4m");
  std::ofstream(slow) << "YUV4MPEG2 W4 H2 F1:99999999 Cmono\n";
  Y4mReader reader;
  CHECK_FALSE(reader.open(slow));
  CHECK(reader.error() == slow + ": frame rate 1:99999999 (1e-08 frames a second) is outside 0.1 to 1000");
  const auto fast = scratch("fast.y4m");
  std::ofstream(fast) << "YUV4MPEG2 W4 H2 F2000:1 Cmono\n";
  CHECK_FALSE(reader.open(fast));
  CHECK(reader.error().find("is outside 0.1 to 1000") != std::string::npos);
  const auto directory = std::filesystem::temp_directory_path().string();
  CHECK_FALSE(reader.open(directory));
  CHECK(reader.error() == directory + ": is a directory, not a YUV4MPEG2 stream");
}
