// Hardware-in-the-loop tests of the V4L2 camera and output against a real
// kernel driver: vivid loaded with n_devs=1 node_types=0x101 (one capture and
// one output node). Run by run-in-vm.sh --with-vivid as root; not meant for
// the host. Nodes: HIL_V4L2_CAPTURE / HIL_V4L2_OUTPUT, else the first vivid
// capture and output nodes found under /dev/video*.
//
// Every test leaves vivid as it found it (controls back to defaults) except
// the removal test, which rebinds the driver and so resets everything.
#include <catch2/catch_test_macros.hpp>

#include <fcntl.h>
#include <linux/videodev2.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <string>
#include <thread>
#include <vector>

#include "drivers/v4l2/v4l2_camera.hpp"
#include "drivers/v4l2/v4l2_output.hpp"
#include "tests/support/count_allocations.hpp"

using namespace markloop::v4l2;
using namespace std::chrono_literals;
using State = V4l2Camera::State;
using Clock = std::chrono::steady_clock;

namespace {

// Streaming and recovery must not touch the heap: every global operator new
// is counted while an AllocationCounter counts.
using markloop::test::AllocationCounter;

// vivid's private controls (drivers/media/test-drivers/vivid/vivid-ctrls.c),
// as listed by `v4l2-ctl -L` on the VM kernel (Linux 6.1).
constexpr std::uint32_t kOsdTextMode = 0x00f0f001;  // 2 = no text over the image
constexpr std::uint32_t kLoopVideo = 0x00f0f025;
constexpr std::uint32_t kPercentDropped = 0x00f0f040;  // buffers vivid drops
constexpr std::uint32_t kInjectBufFlagError = 0x00f0f042;
constexpr std::uint32_t kInjectReqbufsError = 0x00f0f043;
constexpr std::uint32_t kInjectFatalStreamingError = 0x00f0f046;

constexpr int kWebcamInput = 0;
constexpr int kHdmiInput = 3;
constexpr int kHdmiOutput = 1;

std::string env_or(const char* name, const std::string& fallback) {
  const char* v = std::getenv(name);
  return v != nullptr && *v != '\0' ? v : fallback;
}

// The first /dev/videoN of vivid in the given direction.
std::string find_vivid_node(V4l2Device::Direction direction) {
  for (int i = 0; i < 64; ++i) {
    const std::string path = "/dev/video" + std::to_string(i);
    V4l2Device dev;
    DeviceInfo info;
    if (!dev.open(path.c_str(), direction, info) && std::string(info.driver.data()) == "vivid") return path;
  }
  return {};
}

// Looked up once; the strings live as long as the program, so configs may
// keep string_views of them.
const std::string& capture_node() {
  static const std::string node = env_or("HIL_V4L2_CAPTURE", find_vivid_node(V4l2Device::Direction::Capture));
  return node;
}
const std::string& output_node() {
  static const std::string node = env_or("HIL_V4L2_OUTPUT", find_vivid_node(V4l2Device::Direction::Output));
  return node;
}

double ms(std::int64_t ns) {
  return static_cast<double>(ns) / 1e6;
}

// Sets a control through a separate handle (vivid's controls are per device
// instance, so this works while the camera itself is closed or recovering).
std::error_code set_control(const std::string& node, V4l2Device::Direction dir, std::uint32_t id,
                            std::int32_t value) {
  V4l2Device dev;
  DeviceInfo info;
  if (auto ec = dev.open(node.c_str(), dir, info)) return ec;
  return dev.set_control(id, value);
}

// Selects the HDMI input/output and its first DV timings (640x480p59.94).
void select_hdmi_640x480(const std::string& node, V4l2Device::Direction dir) {
  V4l2Device dev;
  DeviceInfo info;
  REQUIRE_FALSE(dev.open(node.c_str(), dir, info));
  if (dir == V4l2Device::Direction::Capture)
    REQUIRE_FALSE(dev.select_input(kHdmiInput));
  else
    REQUIRE_FALSE(dev.select_output(kHdmiOutput));
  v4l2_enum_dv_timings e{};
  e.index = 0;
  REQUIRE_FALSE(dev.ioctl(VIDIOC_ENUM_DV_TIMINGS, &e));
  REQUIRE(e.timings.bt.width == 640);
  REQUIRE(e.timings.bt.height == 480);
  REQUIRE_FALSE(dev.ioctl(VIDIOC_S_DV_TIMINGS, &e.timings));
}

CameraConfig webcam(const std::string& node, PixelFormat format = PixelFormat::Grey) {
  CameraConfig c;
  c.device = node;
  c.input = kWebcamInput;
  c.width = 640;
  c.height = 480;
  c.format = format;
  c.fps = 25;
  c.buffer_count = 4;
  return c;
}

void print_counters(const char* what, const V4l2Camera& cam) {
  const CameraCounters& k = cam.counters();
  std::cout << "[v4l2] " << what << ": state " << to_string(cam.state()) << ", frames " << k.frames
            << ", dropped " << k.dropped << ", buffer_errors " << k.buffer_errors << ", timeouts "
            << k.timeouts << ", stalls " << k.stalls << ", io_errors " << k.io_errors << ", device_lost "
            << k.device_lost << ", recoveries " << k.recoveries_started
            << ", reopen attempts/failures/successes " << k.reopen_attempts << "/" << k.reopen_failures << "/"
            << k.reopen_successes << ", last recovery " << ms(k.last_recovery_ns) << " ms\n";
}

// Waits for frames until one arrives or `timeout` passes; releases it.
bool next_frame(V4l2Camera& cam, std::chrono::milliseconds timeout, FrameView* copy = nullptr) {
  const auto deadline = Clock::now() + timeout;
  while (Clock::now() < deadline) {
    FrameView f;
    if (!cam.wait_frame(f, 100ms)) {
      if (copy != nullptr) *copy = f;
      REQUIRE_FALSE(cam.release(f));
      return true;
    }
  }
  return false;
}

// Waits for a frame, releasing up to `max_late` frames that were already
// done before the stall began (the driver may finish one between our last
// frame and the control change); returns the error that ended the wait.
std::error_code wait_for_silence(V4l2Camera& cam, std::chrono::milliseconds timeout, int max_late = 3) {
  for (int i = 0;; ++i) {
    FrameView f;
    const std::error_code ec = cam.wait_frame(f, timeout);
    if (ec || i >= max_late) {
      if (!ec) (void)cam.release(f);
      return ec ? ec : std::make_error_code(std::errc::io_error);
    }
    (void)cam.release(f);
  }
}

}  // namespace

TEST_CASE("vivid nodes exist") {
  INFO("is vivid loaded? run-in-vm.sh --with-vivid");
  REQUIRE_FALSE(capture_node().empty());
  REQUIRE_FALSE(output_node().empty());
  std::cout << "[v4l2] capture " << capture_node() << ", output " << output_node() << "\n";
}

TEST_CASE("capabilities, format and frame rate of the capture node") {
  V4l2Camera cam;
  REQUIRE_FALSE(cam.open(webcam(capture_node())));
  CHECK(cam.state() == State::Opened);
  const DeviceInfo& info = cam.device_info();
  CHECK(std::string(info.driver.data()) == "vivid");
  CHECK((info.capabilities & V4L2_CAP_VIDEO_CAPTURE) != 0);
  CHECK((info.capabilities & V4L2_CAP_STREAMING) != 0);
  CHECK(cam.format().width == 640);
  CHECK(cam.format().height == 480);
  CHECK(cam.format().stride >= 640);
  CHECK(cam.format().image_size >= 640U * 480U);
  CHECK(cam.frame_interval().settable);
  CHECK(cam.frame_interval().numerator == 1);
  CHECK(cam.frame_interval().denominator == 25);
  CHECK(cam.buffer_count() == 4);
  cam.stop();
  cam.stop();
  CHECK(cam.state() == State::Closed);
}

TEST_CASE("format negotiation: GREY and YUYV accepted, refusals are clean errors") {
  V4l2Camera cam;
  REQUIRE_FALSE(cam.open(webcam(capture_node(), PixelFormat::Grey)));
  CHECK(cam.format().format == PixelFormat::Grey);
  CHECK(cam.format().stride == 640);

  REQUIRE_FALSE(cam.open(webcam(capture_node(), PixelFormat::Yuyv)));
  CHECK(cam.format().format == PixelFormat::Yuyv);
  CHECK(cam.format().stride == 1280);

  // The webcam input has discrete sizes: vivid answers 642x480 with another size.
  CameraConfig odd = webcam(capture_node());
  odd.width = 642;
  CHECK(cam.open(odd) == V4l2Error::SizeRefused);
  CHECK(cam.state() == State::Closed);

  // 640x480 goes up to 25 fps.
  CameraConfig fast = webcam(capture_node());
  fast.fps = 30;
  CHECK(cam.open(fast) == V4l2Error::FrameRateRefused);
  CHECK(cam.state() == State::Closed);

  // The output node is no camera; the capture node is no output.
  CHECK(cam.open(webcam(output_node())) == V4l2Error::NotACaptureDevice);
  V4l2Output out;
  OutputConfig oc;
  oc.device = capture_node();
  CHECK(out.open(oc) == V4l2Error::NotAnOutputDevice);

  // Still usable after all the refusals.
  REQUIRE_FALSE(cam.start(webcam(capture_node())));
  CHECK(next_frame(cam, 3s));
}

TEST_CASE("buffer requests: the driver granting fewer or failing is a clean error") {
  V4l2Camera cam;
  CameraConfig many = webcam(capture_node());
  many.buffer_count = 40;  // vb2 clamps to VIDEO_MAX_FRAME (32)
  CHECK(cam.open(many) == V4l2Error::TooFewBuffers);
  CHECK(cam.state() == State::Closed);

  REQUIRE_FALSE(set_control(capture_node(), V4l2Device::Direction::Capture, kInjectReqbufsError, 1));
  const std::error_code ec = cam.open(webcam(capture_node()));
  std::cout << "[v4l2] injected REQBUFS error: " << ec.message() << "\n";
  CHECK(ec);
  CHECK(cam.state() == State::Closed);

  // The buffers were given back: a normal request works again.
  REQUIRE_FALSE(cam.start(webcam(capture_node())));
  CHECK(cam.buffer_count() == 4);
  CHECK(next_frame(cam, 3s));
}

TEST_CASE("streaming a few hundred frames: sequence and timestamps increase") {
  constexpr int kFrames = 300;
  V4l2Camera cam;
  REQUIRE_FALSE(cam.start(webcam(capture_node())));
  CHECK(cam.state() == State::Streaming);
  std::vector<std::uint32_t> sequences;
  std::vector<std::int64_t> stamps;
  sequences.reserve(kFrames);
  stamps.reserve(kFrames);
  bool all_monotonic = true;
  bool content_varies = false;
  std::error_code failure;
  const std::uint8_t* null_frame = nullptr;
  const auto start = Clock::now();
  AllocationCounter heap;
  while (static_cast<int>(sequences.size()) < kFrames) {
    FrameView f;
    if ((failure = cam.wait_frame(f, 2s))) break;
    if (f.data == nullptr || f.bytes_used < 640U * 480U) {
      null_frame = f.data;
      failure = std::make_error_code(std::errc::bad_message);
      break;
    }
    sequences.push_back(f.sequence);  // reserved: no allocation
    stamps.push_back(f.timestamp_ns);
    all_monotonic = all_monotonic && f.timestamp_monotonic;
    if (f.data[0] != f.data[640 * 480 - 1] || f.data[0] != f.data[320]) content_varies = true;
    if ((failure = cam.release(f))) break;
  }
  const std::size_t heap_allocations = heap.stop();
  INFO("failure: " << failure.message() << " after " << sequences.size() << " frames, data "
                   << static_cast<const void*>(null_frame));
  REQUIRE_FALSE(failure);
  CHECK(heap_allocations == 0);
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  std::uint64_t gaps = 0;
  for (std::size_t i = 1; i < sequences.size(); ++i) {
    CHECK(sequences[i] > sequences[i - 1]);
    CHECK(stamps[i] > stamps[i - 1]);
    gaps += sequences[i] - sequences[i - 1] - 1;
  }
  CHECK(all_monotonic);
  CHECK(content_varies);
  CHECK(cam.counters().frames == kFrames);
  CHECK(cam.counters().dropped == gaps);
  CHECK(cam.counters().recoveries_started == 0);
  const double mean_interval_ms = ms(stamps.back() - stamps.front()) / (kFrames - 1);
  std::cout << "[v4l2] streamed " << kFrames << " frames 640x480 GREY in " << seconds << " s, sequence "
            << sequences.front() << ".." << sequences.back() << ", dropped " << cam.counters().dropped
            << ", mean driver timestamp interval " << mean_interval_ms << " ms\n";
  // 25 fps asked: 40 ms per frame (driver timestamps), with slack for the VM.
  CHECK(mean_interval_ms > 30.0);
  CHECK(mean_interval_ms < 60.0);
  print_counters("stream", cam);
  cam.stop();
  cam.stop();
}

TEST_CASE("YUYV frames give their luma") {
  V4l2Camera cam;
  REQUIRE_FALSE(cam.start(webcam(capture_node(), PixelFormat::Yuyv)));
  FrameView f;
  REQUIRE_FALSE(cam.wait_frame(f, 3s));
  CHECK(f.format == PixelFormat::Yuyv);
  CHECK(f.stride == 1280);
  std::vector<std::uint8_t> luma(640 * 480);
  CHECK(extract_luma(f.format, {f.data, f.bytes_used}, f.width, f.height, f.stride, luma));
  CHECK(luma[0] == f.data[0]);
  CHECK(luma[1] == f.data[2]);
  REQUIRE_FALSE(cam.release(f));
  // Holding every buffer: the camera says so instead of waiting.
  std::vector<FrameView> held(cam.buffer_count());
  for (auto& h : held) REQUIRE_FALSE(cam.wait_frame(h, 3s));
  FrameView extra;
  CHECK(cam.wait_frame(extra, 100ms) == V4l2Error::BuffersExhausted);
  for (auto& h : held) CHECK_FALSE(cam.release(h));
  CHECK(cam.release(held[0]) == std::errc::invalid_argument);  // released twice
}

TEST_CASE("a buffer the driver flags as erroneous is requeued and counted") {
  V4l2Camera cam;
  REQUIRE_FALSE(cam.start(webcam(capture_node())));
  REQUIRE(next_frame(cam, 3s));
  REQUIRE_FALSE(cam.device().set_control(kInjectBufFlagError, 1));
  for (int i = 0; i < 10; ++i) REQUIRE(next_frame(cam, 3s));
  CHECK(cam.counters().buffer_errors == 1);
  CHECK(cam.state() == State::Streaming);
  print_counters("buffer error", cam);
}

TEST_CASE("a stall: no frames -> Stalled, frames again -> Streaming, gap counted as dropped") {
  V4l2Camera cam;
  CameraConfig c = webcam(capture_node());
  c.frame_timeout = 300ms;
  c.stall_restart = 0ms;  // stay Stalled: the gap must show in the sequence numbers
  REQUIRE_FALSE(cam.start(c));
  for (int i = 0; i < 5; ++i) REQUIRE(next_frame(cam, 3s));
  const std::uint64_t dropped_before = cam.counters().dropped;

  REQUIRE_FALSE(cam.device().set_control(kPercentDropped, 100));
  CHECK(wait_for_silence(cam, 1s) == std::errc::timed_out);
  CHECK(cam.state() == State::Stalled);
  CHECK(cam.camera_lost());
  CHECK(cam.counters().stalls == 1);
  CHECK(cam.counters().timeouts >= 1);

  REQUIRE_FALSE(cam.device().set_control(kPercentDropped, 0));
  REQUIRE(next_frame(cam, 3s));
  CHECK(cam.state() == State::Streaming);
  const std::uint64_t lost = cam.counters().dropped - dropped_before;
  std::cout << "[v4l2] stall of ~1 s at 25 fps: " << lost << " frames counted as dropped\n";
  CHECK(lost >= 15);  // 1 s of 25 fps, with slack for the VM
  CHECK(lost <= 60);
  CHECK(cam.counters().recoveries_started == 0);
  print_counters("stall", cam);
}

TEST_CASE("a long stall restarts the stream") {
  V4l2Camera cam;
  CameraConfig c = webcam(capture_node());
  c.frame_timeout = 200ms;
  c.stall_restart = 300ms;
  REQUIRE_FALSE(cam.start(c));
  REQUIRE(next_frame(cam, 3s));
  REQUIRE_FALSE(cam.device().set_control(kPercentDropped, 100));
  CHECK(wait_for_silence(cam, 1500ms) == std::errc::timed_out);
  CHECK(cam.counters().stalls >= 1);
  CHECK(cam.counters().recoveries_started >= 1);
  CHECK(cam.counters().reopen_successes >= 1);  // the device is there: reopening works
  REQUIRE_FALSE(set_control(capture_node(), V4l2Device::Direction::Capture, kPercentDropped, 0));
  REQUIRE(next_frame(cam, 3s));
  CHECK(cam.state() == State::Streaming);
  print_counters("stall restart", cam);
}

TEST_CASE("a fatal streaming error: Recovering, reopen, Streaming again") {
  V4l2Camera cam;
  REQUIRE_FALSE(cam.start(webcam(capture_node())));
  REQUIRE(next_frame(cam, 3s));
  FrameView held;
  REQUIRE_FALSE(cam.wait_frame(held, 3s));
  REQUIRE_FALSE(cam.device().set_control(kInjectFatalStreamingError, 1));
  const auto t0 = Clock::now();
  AllocationCounter heap;
  FrameView after;
  std::error_code ec;
  for (int i = 0; i < 50 && (ec = cam.wait_frame(after, 100ms)); ++i) {
  }
  const std::size_t heap_allocations = heap.stop();
  REQUIRE_FALSE(ec);
  REQUIRE_FALSE(cam.release(after));
  CHECK(heap_allocations == 0);
  const double first_frame_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  CHECK(cam.state() == State::Streaming);
  CHECK(cam.counters().recoveries_started == 1);
  CHECK(cam.counters().reopen_successes == 1);
  CHECK(cam.release(held) == V4l2Error::StaleFrame);  // from before the restart
  std::cout << "[v4l2] fatal streaming error: reopened in " << ms(cam.counters().last_recovery_ns)
            << " ms, first frame after the error " << first_frame_ms << " ms\n";
  print_counters("fatal error", cam);
}

TEST_CASE("output -> capture loop: a written pattern comes back") {
  const std::string& cap = capture_node();
  const std::string& outn = output_node();
  select_hdmi_640x480(cap, V4l2Device::Direction::Capture);
  select_hdmi_640x480(outn, V4l2Device::Direction::Output);
  REQUIRE_FALSE(set_control(cap, V4l2Device::Direction::Capture, kOsdTextMode, 2));
  REQUIRE_FALSE(set_control(cap, V4l2Device::Direction::Capture, kLoopVideo, 1));

  for (PixelFormat format : {PixelFormat::Grey, PixelFormat::Yuyv}) {
    INFO("format " << to_string(format));
    V4l2Output out;
    OutputConfig oc;
    oc.device = outn;
    oc.output = kHdmiOutput;
    oc.format = format;
    REQUIRE_FALSE(out.start(oc));
    V4l2Camera cam;
    CameraConfig cc;
    cc.device = cap;
    cc.input = kHdmiInput;
    cc.format = format;
    cc.fps = 0;  // HDMI: the rate comes from the DV timings
    REQUIRE_FALSE(cam.start(cc));

    // A diagonal ramp shifted by the frame number k, so every frame differs:
    // a captured frame must equal one of those sent (k from its first pixel).
    auto pattern = [](std::uint32_t k, std::uint32_t x, std::uint32_t y) {
      return static_cast<std::uint8_t>((x + 2 * y + k) & 0xFF);
    };
    std::vector<std::uint8_t> luma(640 * 480);
    std::vector<std::uint8_t> seen(640 * 480);
    int matched = 0;
    std::uint32_t sent = 0;
    std::uint32_t distinct_matches = 0;
    int last_k = -1;
    std::size_t best_mismatch = luma.size();
    const auto deadline = Clock::now() + 10s;
    while ((matched < 20 || distinct_matches < 10) && Clock::now() < deadline) {
      for (std::uint32_t y = 0; y < 480; ++y)
        for (std::uint32_t x = 0; x < 640; ++x) luma[y * 640 + x] = pattern(sent, x, y);
      const std::error_code sec = out.send_luma(luma, 200ms);
      if (!sec)
        ++sent;
      else if (sec != std::errc::timed_out)
        FAIL("send_luma: " << sec.message());
      FrameView f;
      if (cam.wait_frame(f, 100ms)) continue;
      REQUIRE(extract_luma(f.format, {f.data, f.bytes_used}, f.width, f.height, f.stride, seen));
      REQUIRE_FALSE(cam.release(f));
      const std::uint32_t k = seen[0];
      std::size_t mismatch = 0;
      for (std::uint32_t y = 0; y < 480; ++y)
        for (std::uint32_t x = 0; x < 640; ++x) mismatch += seen[y * 640 + x] != pattern(k, x, y);
      best_mismatch = std::min(best_mismatch, mismatch);
      if (mismatch == 0 && k < sent) {
        ++matched;
        if (static_cast<int>(k) != last_k) ++distinct_matches;
        last_k = static_cast<int>(k);
      }
    }
    std::cout << "[v4l2] loop " << to_string(format) << ": " << out.counters().frames_queued
              << " frames written, " << out.counters().frames_done << " done, " << cam.counters().frames
              << " captured, " << matched << " identical to a frame sent (" << distinct_matches
              << " different frames; fewest differing pixels " << best_mismatch << ")\n";
    CHECK(matched >= 20);
    CHECK(distinct_matches >= 10);
  }
  REQUIRE_FALSE(set_control(cap, V4l2Device::Direction::Capture, kLoopVideo, 0));
  REQUIRE_FALSE(set_control(cap, V4l2Device::Direction::Capture, kOsdTextMode, 0));
}

// Last: unbinding vivid removes the device nodes; rebinding recreates them
// with default settings.
TEST_CASE("device removal: Recovering with back-off, back to Streaming after rebind") {
  const std::string& node = capture_node();
  V4l2Camera cam;
  CameraConfig c = webcam(node);
  c.backoff_min = 20ms;
  c.backoff_max = 200ms;
  REQUIRE_FALSE(cam.start(c));
  REQUIRE(next_frame(cam, 3s));

  const char* unbind = "/sys/bus/platform/drivers/vivid/unbind";
  const char* bind = "/sys/bus/platform/drivers/vivid/bind";
  {
    std::ofstream u(unbind);
    REQUIRE(u.good());
    u << "vivid.0" << std::flush;
    REQUIRE(u.good());
  }
  const auto removed_at = Clock::now();
  FrameView f;
  CHECK(cam.wait_frame(f, 1s) == std::errc::timed_out);
  CHECK(cam.state() == State::Recovering);
  CHECK(cam.camera_lost());
  CHECK(cam.counters().recoveries_started == 1);
  CHECK(cam.counters().device_lost == 1);
  CHECK(cam.counters().reopen_failures >= 1);
  std::cout << "[v4l2] device removed: " << cam.last_error().message() << "\n";
  // Stay away for 1 s: the back-off must keep attempts few (20..200 ms doubling).
  CHECK(cam.wait_frame(f, 1s) == std::errc::timed_out);
  const std::uint64_t attempts_while_gone = cam.counters().reopen_attempts;
  CHECK(attempts_while_gone >= 3);
  CHECK(attempts_while_gone <= 20);

  {
    std::ofstream b(bind);
    REQUIRE(b.good());
    b << "vivid.0" << std::flush;
    REQUIRE(b.good());
  }
  const auto bound_at = Clock::now();
  REQUIRE(next_frame(cam, 10s));
  const double back_ms = std::chrono::duration<double, std::milli>(Clock::now() - bound_at).count();
  const double outage_ms = std::chrono::duration<double, std::milli>(Clock::now() - removed_at).count();
  CHECK(cam.state() == State::Streaming);
  CHECK_FALSE(cam.camera_lost());
  CHECK(cam.counters().reopen_successes == 1);
  std::cout << "[v4l2] removal: " << attempts_while_gone << " reopen attempts while gone; first frame "
            << back_ms << " ms after rebind; outage " << outage_ms << " ms; camera recovery time "
            << ms(cam.counters().last_recovery_ns) << " ms\n";
  for (int i = 0; i < 25; ++i) REQUIRE(next_frame(cam, 3s));
  print_counters("removal", cam);
}
