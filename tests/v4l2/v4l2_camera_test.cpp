// What can be checked about the V4L2 camera and output without a video
// device: argument validation, the state machine on missing nodes and on
// files that are not devices.
#include <catch2/catch_test_macros.hpp>

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <string>

#include "drivers/v4l2/v4l2_camera.hpp"
#include "drivers/v4l2/v4l2_output.hpp"

using namespace markloop::v4l2;
using namespace std::chrono_literals;
using State = V4l2Camera::State;

namespace {

// A regular file for the duration of a test: ioctls on it fail with ENOTTY.
struct TempFile {
  std::string path;
  TempFile() {
    char name[] = "/tmp/markloop-v4l2-XXXXXX";
    const int fd = ::mkstemp(name);
    REQUIRE(fd >= 0);
    REQUIRE(::write(fd, "not a camera", 12) == 12);
    ::close(fd);
    path = name;
  }
  ~TempFile() { ::unlink(path.c_str()); }
};

}  // namespace

TEST_CASE("a closed camera refuses work and stop is idempotent") {
  V4l2Camera cam;
  CHECK(cam.state() == State::Closed);
  FrameView f;
  CHECK(cam.wait_frame(f, 10ms) == V4l2Error::NotStreaming);
  CHECK(cam.release(f) == V4l2Error::StaleFrame);  // generation 0 is never handed out
  CHECK(cam.start() == V4l2Error::NotStreaming);
  CHECK(cam.recovery_wait() == 0ms);
  cam.stop();
  cam.stop();
  CHECK(cam.state() == State::Closed);
  CHECK(cam.buffer_count() == 0);
}

TEST_CASE("camera configuration is validated before the kernel is touched") {
  const CameraConfig good;
  CHECK_FALSE(V4l2Camera::validate(good));
  auto bad = [](auto change) {
    CameraConfig c;
    change(c);
    return V4l2Camera::validate(c) == std::errc::invalid_argument;
  };
  CHECK(bad([](CameraConfig& c) { c.device = ""; }));
  CHECK(bad([](CameraConfig& c) { c.device = std::string_view("/dev/video0\0x", 13); }));
  static const std::string long_path(200, 'a');
  CHECK(bad([](CameraConfig& c) { c.device = long_path; }));
  CHECK(bad([](CameraConfig& c) { c.width = 0; }));
  CHECK(bad([](CameraConfig& c) { c.height = 20000; }));
  CHECK(bad([](CameraConfig& c) {
    c.format = PixelFormat::Yuyv;
    c.width = 641;
  }));
  CHECK(bad([](CameraConfig& c) { c.buffer_count = 0; }));
  CHECK(bad([](CameraConfig& c) { c.buffer_count = V4l2Device::kMaxBuffers + 1; }));
  CHECK(bad([](CameraConfig& c) { c.fps = 5000; }));
  CHECK(bad([](CameraConfig& c) { c.input = -2; }));
  CHECK(bad([](CameraConfig& c) { c.frame_timeout = 0ms; }));
  CHECK(bad([](CameraConfig& c) { c.backoff_min = 0ms; }));
  CHECK(bad([](CameraConfig& c) {
    c.backoff_max = 1ms;
    c.backoff_min = 2ms;
  }));
  CHECK(bad([](CameraConfig& c) { c.max_consecutive_errors = 0; }));

  V4l2Camera cam;
  CameraConfig c;
  c.width = 0;
  CHECK(cam.start(c) == std::errc::invalid_argument);
  CHECK(cam.state() == State::Closed);
}

TEST_CASE("a missing device node fails cleanly") {
  V4l2Camera cam;
  CameraConfig c;
  c.device = "/dev/markloop-no-such-video";
  const std::error_code ec = cam.start(c);
  CHECK(ec == std::errc::no_such_file_or_directory);
  CHECK(cam.state() == State::Closed);
  CHECK(cam.last_error() == ec);
  FrameView f;
  CHECK(cam.wait_frame(f, 1ms) == V4l2Error::NotStreaming);
}

TEST_CASE("a regular file is not a V4L2 device") {
  TempFile file;
  V4l2Camera cam;
  CameraConfig c;
  c.device = file.path;
  CHECK(cam.open(c) == std::errc::inappropriate_io_control_operation);  // ENOTTY from QUERYCAP
  CHECK(cam.state() == State::Closed);

  V4l2Output out;
  OutputConfig oc;
  oc.device = file.path;
  CHECK(out.start(oc) == std::errc::inappropriate_io_control_operation);
  CHECK(out.state() == V4l2Output::State::Closed);
}

TEST_CASE("a character device that is not V4L2 answers ENOTTY") {
  V4l2Device dev;
  DeviceInfo info;
  CHECK(dev.open("/dev/null", V4l2Device::Direction::Capture, info) ==
        std::errc::inappropriate_io_control_operation);
  CHECK_FALSE(dev.is_open());
  CHECK(dev.open("", V4l2Device::Direction::Capture, info) == std::errc::invalid_argument);
  CHECK(dev.open(nullptr, V4l2Device::Direction::Capture, info) == std::errc::invalid_argument);
  // Nothing open: every request fails instead of touching fd -1.
  CHECK(dev.stream_on() == std::errc::bad_file_descriptor);
  CHECK(dev.queue(0, 0) == std::errc::invalid_argument);
  CHECK(dev.request_buffers(0, 1) == std::errc::invalid_argument);
  CHECK(dev.request_buffers(V4l2Device::kMaxBuffers + 1, 1) == std::errc::invalid_argument);
  dev.close();
  dev.close();
}

TEST_CASE("a closed output refuses work and validates its configuration") {
  V4l2Output out;
  OutputBuffer b;
  CHECK(out.acquire(b, 1ms) == V4l2Error::NotStreaming);
  CHECK(out.submit(b, 1) == V4l2Error::NotStreaming);
  const std::uint8_t luma[4] = {};
  CHECK(out.send_luma(luma, 1ms) == V4l2Error::NotStreaming);
  CHECK(out.start() == V4l2Error::NotStreaming);
  out.stop();
  out.stop();
  OutputConfig c;
  CHECK_FALSE(V4l2Output::validate(c));
  c.buffer_count = 0;
  CHECK(V4l2Output::validate(c) == std::errc::invalid_argument);
  c = OutputConfig{};
  c.output = -5;
  CHECK(out.open(c) == std::errc::invalid_argument);
  c = OutputConfig{};
  c.device = "/dev/markloop-no-such-video";
  CHECK(out.open(c) == std::errc::no_such_file_or_directory);
  CHECK(out.state() == V4l2Output::State::Closed);
}

TEST_CASE("state names") {
  CHECK(std::string(to_string(State::Recovering)) == "Recovering");
  CHECK(std::string(to_string(State::Stalled)) == "Stalled");
  CHECK(std::string(to_string(V4l2Output::State::Streaming)) == "Streaming");
}
