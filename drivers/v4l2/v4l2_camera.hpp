// V4L2 capture camera on the raw kernel API: one object per video node.
//
// States (explicit, see State):
//   Closed     --open() ok-->      Opened     (capabilities, format, rate and
//                                              buffers negotiated, mapped)
//   Opened     --start() ok-->     Streaming  (all buffers queued, STREAMON)
//   Closed     --start() ok-->     Streaming  (open() done on the way)
//   Streaming  --no frame for frame_timeout-->           Stalled
//   Stalled    --a frame arrives-->                      Streaming
//   Stalled    --still nothing after stall_restart-->    Recovering
//   Streaming/Stalled --ENODEV/ENXIO/EIO/EPIPE, POLLERR, or
//                       max_consecutive_errors failures-->  Recovering
//   Recovering --reopen + renegotiate + STREAMON ok (tried from wait_frame
//                with back-off doubling from backoff_min to backoff_max)-->
//                Streaming
//   any        --stop()-->         Closed      (safe any number of times)
//
// Frames: wait_frame() hands out a non-owning FrameView into an mmap buffer
// (no copy); release() gives it back to the driver. A view stays valid until
// it is released or until wait_frame() starts a recovery (the buffers are
// unmapped then; views carry the stream generation, so releasing a stale
// one is refused with StaleFrame). Buffers flagged V4L2_BUF_FLAG_ERROR, with
// an index out of range or with too few bytes are requeued and counted,
// never returned. Gaps in the driver's sequence numbers count as dropped
// frames. Timestamps are the driver's (CLOCK_MONOTONIC for vb2 drivers).
//
// Rules: no exceptions, no heap (buffer table and path are fixed arrays),
// every ioctl through V4l2Device::ioctl -> platform::sys_ioctl, counters
// instead of logging.
//
// Found with vivid (Linux 6.1, n_devs=1 node_types=0x101): capture and output
// both offer GREY and YUYV. The webcam input (0) has discrete sizes
// 320x180..3840x2160 and rates (640x480: 1..25 fps); the HDMI input (3) takes
// its size and 60 Hz rate from DV timings and has no settable rate. Output
// looping (control loop_video on the capture node) needs capture input HDMI,
// output HDMI (1), the same DV timings, pixel format and size on both; then
// GREY and YUYV frames come back bit-exact (no conversion needed). Removal:
// writing vivid.0 to /sys/bus/platform/drivers/vivid/unbind makes open fds
// fail with ENODEV/POLLHUP and the nodes vanish; .../bind brings them back
// with default settings. A stall: control percentage_of_dropped_buffers=100
// (vivid keeps numbering the frames it drops, so the gap shows as dropped).
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string_view>
#include <system_error>

#include "drivers/v4l2/v4l2_device.hpp"
#include "drivers/v4l2/v4l2_format.hpp"

namespace markloop::v4l2 {

struct CameraConfig {
  std::string_view device = "/dev/video0";  // copied by open()/start()
  int input = -1;                           // VIDIOC_S_INPUT index; -1 keeps the current one
  std::uint32_t width = 640;
  std::uint32_t height = 480;
  PixelFormat format = PixelFormat::Grey;
  std::uint32_t fps = 0;                          // 0 keeps the driver's rate
  std::uint32_t buffer_count = 4;                 // exactly this many, or open() fails
  std::chrono::milliseconds frame_timeout{500};   // no frame this long: Stalled
  std::chrono::milliseconds stall_restart{2000};  // Stalled this long: Recovering (0: never)
  std::chrono::milliseconds backoff_min{20};
  std::chrono::milliseconds backoff_max{1000};
  unsigned max_consecutive_errors = 8;
};

// A frame still owned by the driver's mmap buffer. Not owning: give it back
// with V4l2Camera::release().
struct FrameView {
  const std::uint8_t* data = nullptr;
  std::uint32_t bytes_used = 0;
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::uint32_t stride = 0;
  PixelFormat format = PixelFormat::Grey;
  std::uint32_t sequence = 0;        // driver's frame number
  std::int64_t timestamp_ns = 0;     // driver's timestamp
  bool timestamp_monotonic = false;  // V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC
  std::uint32_t index = 0;           // buffer index (for release)
  std::uint32_t generation = 0;      // stream generation (for release)
};

struct CameraCounters {
  std::uint64_t frames = 0;             // frames handed out
  std::uint64_t dropped = 0;            // gaps in the driver's sequence numbers
  std::uint64_t sequence_restarts = 0;  // sequence went backwards (not a restart of ours)
  std::uint64_t buffer_errors = 0;      // V4L2_BUF_FLAG_ERROR buffers (requeued)
  std::uint64_t bad_buffers = 0;        // bad index or bytesused (requeued)
  std::uint64_t timeouts = 0;           // wait_frame() calls that timed out
  std::uint64_t stalls = 0;             // Streaming -> Stalled
  std::uint64_t io_errors = 0;          // ioctl/poll failures while streaming
  std::uint64_t device_lost = 0;        // ENODEV/ENXIO/POLLHUP: device gone
  std::uint64_t recoveries_started = 0;
  std::uint64_t reopen_attempts = 0;
  std::uint64_t reopen_failures = 0;
  std::uint64_t reopen_successes = 0;
  std::int64_t last_recovery_ns = 0;  // Recovering -> Streaming, last time
  std::int64_t max_recovery_ns = 0;
};

class V4l2Camera {
 public:
  enum class State { Closed, Opened, Streaming, Stalled, Recovering };
  using Clock = std::chrono::steady_clock;
  static constexpr std::size_t kMaxPath = 128;

  V4l2Camera() = default;
  ~V4l2Camera() { stop(); }
  V4l2Camera(const V4l2Camera&) = delete;
  V4l2Camera& operator=(const V4l2Camera&) = delete;

  // Validates `config`, opens the node and negotiates everything.
  // Closed -> Opened; on failure stays Closed and says why (system errno or
  // V4l2Error; invalid_argument for a bad config, without touching the kernel).
  std::error_code open(const CameraConfig& config) noexcept;
  // Queues every buffer and starts streaming (opening first when Closed).
  std::error_code start(const CameraConfig& config) noexcept;
  std::error_code start() noexcept;  // Opened -> Streaming with the stored config
  // Stops streaming and closes. Safe any number of times; counters stay.
  void stop() noexcept;

  // Waits up to `timeout` for the next frame. {} with `out` filled, or:
  // timed_out (nothing in time; state says Streaming/Stalled/Recovering),
  // V4l2Error::NotStreaming (Closed/Opened), V4l2Error::BuffersExhausted
  // (the caller holds every buffer). Recovery runs inside this call.
  std::error_code wait_frame(FrameView& out, std::chrono::milliseconds timeout) noexcept;
  // Gives a frame back to the driver. StaleFrame for a view of an earlier
  // stream, invalid_argument for one not handed out.
  std::error_code release(const FrameView& frame) noexcept;

  State state() const noexcept { return state_; }
  // No frame within frame_timeout, or the device is being reopened: what the
  // Status message reports as FaultCameraLost (with counters().dropped as
  // FramesDropped).
  bool camera_lost() const noexcept { return state_ == State::Stalled || state_ == State::Recovering; }
  const CameraCounters& counters() const noexcept { return counters_; }
  const DeviceInfo& device_info() const noexcept { return info_; }
  const NegotiatedFormat& format() const noexcept { return format_; }
  const FrameInterval& frame_interval() const noexcept { return interval_; }
  std::size_t buffer_count() const noexcept { return device_.buffer_count(); }
  std::size_t buffers_held() const noexcept { return held_count_; }
  // The last error that sent the camera to Recovering (or failed a reopen).
  std::error_code last_error() const noexcept { return last_error_; }
  // Time until the next reopen attempt (zero unless Recovering).
  std::chrono::milliseconds recovery_wait() const noexcept;
  // The node, for controls and tests (V4l2Device::set_control...).
  V4l2Device& device() noexcept { return device_; }

  static std::error_code validate(const CameraConfig& config) noexcept;

 private:
  std::error_code open_stored() noexcept;   // open + negotiate from config_
  std::error_code start_stream() noexcept;  // queue all + STREAMON
  void enter_recovering(std::error_code why) noexcept;
  void attempt_reopen() noexcept;
  void note_streaming_error(std::error_code ec) noexcept;
  bool handle_buffer(const v4l2_buffer& buf, FrameView& out) noexcept;  // true: frame for caller
  // The steps of wait_frame(): each returns what wait_frame() returns, or
  // nothing to go round again.
  std::optional<std::error_code> wait_while_recovering(Clock::time_point deadline,
                                                       Clock::time_point now) noexcept;
  std::optional<std::error_code> dequeue_or_sleep(FrameView& out, Clock::time_point deadline,
                                                  Clock::time_point now, bool& poll_error) noexcept;
  std::optional<std::error_code> sleep_until_ready(Clock::time_point deadline, Clock::time_point now,
                                                   bool& poll_error) noexcept;
  // After a poll() that timed out: marks a stall, restarts a long one.
  std::optional<std::error_code> check_stall(Clock::time_point deadline, Clock::time_point stall_at,
                                             Clock::time_point restart_at) noexcept;

  V4l2Device device_;
  State state_ = State::Closed;
  CameraConfig config_{};
  std::array<char, kMaxPath> path_{};
  DeviceInfo info_{};
  NegotiatedFormat format_{};
  FrameInterval interval_{};
  std::array<bool, V4l2Device::kMaxBuffers> held_{};
  std::size_t held_count_ = 0;
  std::uint32_t generation_ = 1;  // views default to 0: never current
  SequenceTracker sequence_;
  CameraCounters counters_{};
  std::error_code last_error_{};
  unsigned consecutive_errors_ = 0;
  Clock::time_point last_frame_{};
  Clock::time_point recovery_started_{};
  Clock::time_point next_attempt_{};
  std::chrono::milliseconds backoff_{0};
};

const char* to_string(V4l2Camera::State state) noexcept;

}  // namespace markloop::v4l2
