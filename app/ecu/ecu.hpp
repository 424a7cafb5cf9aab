// The ECU's work, device-independent: camera frames and CAN frames in,
// LoopDetection and Status frames out. The runners (file_runner, live_runner)
// own the devices and the clock and call in here; tests call in with fakes.
//
// Per frame: detect and classify markings, place them on the ground, move
// them into the world frame with the odometry pose, run the sequence engine
// (landmarks, sequences, database, match, verify) and send every loop
// detection at once. Everything is allocated in the constructor.
//
// Time: `Nanoseconds` values are the ECU's time base (file mode: seconds of
// the recording; live: CLOCK_MONOTONIC since start). Processing times are
// measured with the steady clock.
#pragma once

#include <chrono>
#include <cstdint>
#include <span>

#include <opencv2/core/mat.hpp>

#include "app/common/fixed_vector.hpp"
#include "app/ecu/config.hpp"
#include "app/ecu/map_store.hpp"
#include "app/ecu/odometry.hpp"
#include "app/ecu/timing.hpp"
#include "app/engine/sequence_engine.hpp"
#include "app/perception/camera_model.hpp"
#include "app/perception/marking_detector.hpp"
#include "dbc/e2e.hpp"
#include "drivers/can/can_frame.hpp"

namespace markloop::ecu {

using SteadyClock = std::chrono::steady_clock;

struct EcuCounters {
  std::uint64_t frames_processed = 0;
  std::uint64_t frames_dropped = 0;       // skipped (overrun) or lost by the camera
  std::uint64_t frames_over_rate = 0;     // skipped on purpose: above camera.max_rate
  std::uint64_t frames_without_pose = 0;  // processed for detection only
  std::uint64_t frames_blind = 0;         // processed, but showed no road (perception::ViewKind)
  std::uint64_t overruns = 0;             // processing took longer than a frame period
  std::uint64_t detections = 0;
  std::uint64_t detections_rejected = 0;  // unknown label or non-finite position
  std::uint64_t detections_gated = 0;     // below the score or outside the range (ObservationGate)
  std::uint64_t pose_losses = 0;          // chains broken because the pose became unknown
  std::uint64_t loop_detections = 0;
  std::uint64_t frames_sent = 0;
  std::uint64_t send_errors = 0;  // the bus refused a frame (down, bus-off, queue full)
  std::uint64_t status_cycles = 0;
  std::uint64_t foreign_frames = 0;  // ids markloop does not receive
  std::uint64_t bad_frames = 0;      // extended/remote/oversized on our ids
  std::uint64_t commands_accepted = 0;
  std::uint64_t commands_rejected = 0;  // CRC, counter, length or unknown code
  std::uint64_t database_resets = 0;
  std::uint64_t map_saves = 0;
  std::uint64_t map_save_failures = 0;
  std::uint64_t can_frames_unused = 0;  // file mode: log frames after the last camera frame
};

struct EcuFaults {
  bool camera_lost = false;
  bool camera_blind = false;
  bool odometry_timeout = false;
  bool bus_error = false;
  bool overrun = false;
};

class Ecu final : private MatchSink {
 public:
  // `bus` and `log` receive every frame sent; either may be null.
  Ecu(const EcuConfig& config, const perception::CameraModel& camera,
      const perception::DetectorConfig& detector_config, can::CanFrameSink* bus, can::CanFrameSink* log);

  // Start-up: fill the database from the map file (see MapStore).
  MapLoadResult load_map();
  // Save the database now (command, shutdown). Blocking file I/O.
  std::error_code save_map() noexcept;

  // A received CAN frame (odometry, command, or anything else on the bus).
  void on_can_frame(const can::CanFrame& frame, Nanoseconds now) noexcept;

  // One camera frame, captured at `frame_time`, handed to the ECU at
  // `arrival`. Sent frames are stamped frame_time + (send - arrival).
  // Returns this frame's detections (valid until the next call).
  std::span<const perception::Detection> on_frame(const cv::Mat& grey, Nanoseconds frame_time,
                                                  SteadyClock::time_point arrival) noexcept;
  // The part of on_frame() after the detector, for detections that come from
  // elsewhere (tests, recorded detections).
  void on_detections(std::span<const perception::Detection> detections, Nanoseconds frame_time,
                     SteadyClock::time_point arrival) noexcept {
    process(detections, frame_time, arrival, SteadyClock::now());
  }
  // A frame that was not processed (late: the loop overran) or lost.
  void count_dropped_frames(std::uint64_t n) noexcept {
    counters_.frames_dropped += n;
    dropped_in_cycle_ += n;
  }
  void count_unused_can_frames(std::uint64_t n) noexcept { counters_.can_frames_unused += n; }

  // A frame skipped on purpose (camera.max_rate).
  void count_frame_over_rate() noexcept { ++counters_.frames_over_rate; }

  // Deadlines the loop missed (status timer expirations beyond one).
  void count_overruns(std::uint64_t n) noexcept {
    counters_.overruns += n;
    overruns_in_cycle_ += n;
  }

  // The Status pages, stamped `now`. Call every status period.
  void send_status(Nanoseconds now) noexcept;
  // Device state the runner sees.
  void set_camera_lost(bool lost) noexcept { camera_lost_ = lost; }
  void set_bus_fault(bool fault) noexcept { bus_fault_ = fault; }

  // End of a recording: commit what is still in flight (may send detections).
  void finish(Nanoseconds now) noexcept;

  // The number the next frame gets (file mode: the recording's frame index,
  // so that frames on the bus name frames of the recording).
  void set_next_frame(FrameIndex index) noexcept { next_frame_ = index; }

  // Added to every stamp (live mode: CLOCK_REALTIME of the time base's zero,
  // so logs carry wall-clock time like candump's).
  void set_stamp_offset(Nanoseconds offset) noexcept { stamp_offset_ = offset; }

  const EcuCounters& counters() const noexcept { return counters_; }
  EcuFaults faults(Nanoseconds now) noexcept;
  const OdometryIntegrator& odometry() const noexcept { return odometry_; }
  const SequenceEngine& engine() const noexcept { return engine_; }
  const perception::MarkingDetector& detector() const noexcept { return detector_; }
  const TimingHistogram& detect_time() const noexcept { return detect_time_; }
  const TimingHistogram& engine_time() const noexcept { return engine_time_; }
  const TimingHistogram& frame_time() const noexcept { return frame_time_; }
  // From the frame's capture time to each LoopDetection's first page.
  const TimingHistogram& detection_latency() const noexcept { return detection_latency_; }
  const MapStore& map_store() const noexcept { return map_store_; }

 private:
  void on_match(const MatchEvent& event) override;
  void process(std::span<const perception::Detection> detections, Nanoseconds frame_time,
               SteadyClock::time_point arrival, SteadyClock::time_point started) noexcept;
  void send(const can::CanFrame& frame, Nanoseconds stamp) noexcept;
  void handle_command(const can::CanFrame& frame) noexcept;
  void clear_database() noexcept;
  void judge_camera(perception::ViewKind view) noexcept;
  Nanoseconds frame_period() const noexcept { return frame_period_; }

  EcuConfig config_;
  perception::MarkingDetector detector_;
  SequenceEngine engine_;
  OdometryIntegrator odometry_;
  MapStore map_store_;
  can::CanFrameSink* bus_;
  can::CanFrameSink* log_;
  Nanoseconds frame_period_;

  dbc::E2eSenderState loop_sender_;
  dbc::E2eSenderState status_sender_;
  dbc::E2eReceiverState command_receiver_;
  std::uint8_t next_match_id_ = 0;

  FixedVector<Observation, SequenceEngine::kMaxObservationsPerFrame> observations_;
  FrameIndex next_frame_ = 0;
  bool pose_was_known_ = false;
  bool camera_lost_ = false;
  bool camera_blind_ = false;
  unsigned views_in_a_row_ = 0;  // frames in a row that would change camera_blind_
  bool bus_fault_ = false;
  Nanoseconds stamp_offset_{0};
  // Context of the frame being processed, for on_match().
  Nanoseconds current_frame_time_{0};
  SteadyClock::time_point current_arrival_{};

  // Per status cycle.
  std::uint64_t dropped_in_cycle_ = 0;
  std::uint64_t overruns_in_cycle_ = 0;
  std::uint64_t bus_errors_in_cycle_ = 0;
  std::int64_t loop_time_max_ns_ = 0;
  EcuFaults last_faults_{};

  EcuCounters counters_;
  TimingHistogram detect_time_;
  TimingHistogram engine_time_;
  TimingHistogram frame_time_;
  TimingHistogram detection_latency_;
};

}  // namespace markloop::ecu
