#include "app/ecu/ecu.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "app/common/units.hpp"
#include "app/ecu/observation.hpp"
#include "app/perception/marking_classes.hpp"
#include "dbc/markloop_messages.hpp"
#include "dbc/receive.hpp"

namespace markloop::ecu {

namespace {

can::CanFrame to_can(const dbc::CanFrame& frame) {
  can::CanFrame out;
  out.id = frame.id;
  out.dlc = frame.length;
  out.data = frame.data;
  return out;
}

double seconds(Nanoseconds t) {
  return std::chrono::duration<double>(t).count();
}

std::uint32_t saturate32(std::uint64_t v) {
  return v > 0xFFFFFFFFu ? 0xFFFFFFFFu : static_cast<std::uint32_t>(v);
}

}  // namespace

Ecu::Ecu(const EcuConfig& config, const perception::CameraModel& camera,
         const perception::DetectorConfig& detector_config, can::CanFrameSink* bus, can::CanFrameSink* log)
    : config_(config),
      detector_(camera, detector_config),
      engine_(config.engine),
      odometry_(std::chrono::milliseconds(config.odometry_timeout_ms)),
      map_store_(config.map_file),
      bus_(bus),
      log_(log),
      frame_period_(
          std::chrono::nanoseconds(1'000'000'000LL / (config.camera.fps == 0 ? 10U : config.camera.fps))) {}

MapLoadResult Ecu::load_map() {
  return map_store_.load(engine_.mutable_database(), config_.engine.match);
}

std::error_code Ecu::save_map() noexcept {
  const std::error_code ec = map_store_.save(engine_.database());
  if (ec)
    ++counters_.map_save_failures;
  else if (!map_store_.path().empty())
    ++counters_.map_saves;
  return ec;
}

void Ecu::send(const can::CanFrame& frame, Nanoseconds stamp) noexcept {
  can::CanFrame stamped = frame;
  // 0 means "no timestamp" to the sinks: the first instant of a recording is 1 ns.
  stamped.timestamp_ns = std::max<std::int64_t>(1, (stamp + stamp_offset_).count());
  ++counters_.frames_sent;
  if (bus_ != nullptr && bus_->send(stamped)) {
    ++counters_.send_errors;
    ++bus_errors_in_cycle_;
  }
  if (log_ != nullptr) (void)log_->send(stamped);
}

void Ecu::on_can_frame(const can::CanFrame& frame, Nanoseconds now) noexcept {
  const bool ours =
      !frame.extended && (frame.id == dbc::VehicleOdometry::kId || frame.id == dbc::Command::kId);
  if (!ours) {
    ++counters_.foreign_frames;
    return;
  }
  if (!frame.valid()) {
    ++counters_.bad_frames;
    ++bus_errors_in_cycle_;
    return;
  }
  if (frame.id == dbc::VehicleOdometry::kId) {
    if (odometry_.receive(frame.payload(), now) != dbc::DecodeError::None) ++bus_errors_in_cycle_;
    return;
  }
  handle_command(frame);
}

void Ecu::handle_command(const can::CanFrame& frame) noexcept {
  dbc::Command command;
  if (dbc::decode(frame.payload(), command_receiver_, command) != dbc::DecodeError::None) {
    ++counters_.commands_rejected;
    ++bus_errors_in_cycle_;
    return;
  }
  ++counters_.commands_accepted;
  switch (command.command_code) {
    case dbc::CommandCode::ResetDatabase:
      clear_database();
      break;
    case dbc::CommandCode::SaveMap:
      (void)save_map();
      break;
    default:
      ++counters_.commands_rejected;
      break;
  }
}

void Ecu::clear_database() noexcept {
  // What is in flight belongs to the old map: let it go, then forget everything.
  engine_.break_chains(*this);
  engine_.mutable_database().clear();
  ++counters_.database_resets;
}

std::span<const perception::Detection> Ecu::on_frame(const cv::Mat& grey, Nanoseconds frame_time,
                                                     SteadyClock::time_point arrival) noexcept {
  const auto started = SteadyClock::now();
  const std::span<const perception::Detection> detections = detector_.detect(grey);
  detect_time_.add(SteadyClock::now() - started);
  judge_camera(detector_.last_view());
  process(detections, frame_time, arrival, started);
  return detections;
}

void Ecu::judge_camera(perception::ViewKind view) noexcept {
  // A lens covered for a moment or one garbled frame is not a fault; a run of
  // them is, and as long a run of road ends it.
  const bool shows_road = view == perception::ViewKind::Road;
  if (!shows_road) ++counters_.frames_blind;
  if (shows_road == camera_blind_) {
    if (++views_in_a_row_ >= config_.camera.blind_frames) {
      camera_blind_ = !camera_blind_;
      views_in_a_row_ = 0;
    }
  } else {
    views_in_a_row_ = 0;
  }
}

void Ecu::process(std::span<const perception::Detection> detections, Nanoseconds frame_time,
                  SteadyClock::time_point arrival, SteadyClock::time_point started) noexcept {
  current_frame_time_ = frame_time;
  current_arrival_ = arrival;
  const auto detected = SteadyClock::now();

  FrameInput input;
  input.frame = next_frame_++;
  input.t = seconds(frame_time);
  input.has_pose = odometry_.pose_known(frame_time);
  observations_.clear();
  if (input.has_pose) {
    input.pose = odometry_.pose_at(frame_time);
    for (const perception::Detection& d : detections) {
      Observation o;
      const Observed observed =
          d.label < perception::kMarkingClassCount
              ? observe(d.label, d.score, d.turned, d.ground_x, d.ground_y, input.pose, config_.gate, o)
              : Observed::kRejected;
      if (observed == Observed::kGated)
        ++counters_.detections_gated;
      else if (observed != Observed::kYes || !observations_.push_back(o))
        ++counters_.detections_rejected;
    }
  } else {
    // Without a pose the markings cannot be placed in the world: detect only,
    // and break the chains once so that no sequence spans the gap.
    ++counters_.frames_without_pose;
    if (pose_was_known_) {
      engine_.break_chains(*this);
      ++counters_.pose_losses;
    }
  }
  pose_was_known_ = input.has_pose;
  counters_.detections += detections.size();
  engine_.process_frame(input, observations_.span(), *this);
  const auto finished = SteadyClock::now();

  ++counters_.frames_processed;
  engine_time_.add(finished - detected);
  frame_time_.add(finished - started);
  loop_time_max_ns_ = std::max<std::int64_t>(loop_time_max_ns_, (finished - started).count());
  if (finished - arrival > frame_period_) {
    ++counters_.overruns;
    ++overruns_in_cycle_;
  }
}

void Ecu::on_match(const MatchEvent& event) {
  const unsigned k = event.k;
  if (k == 0 || k > kMaxSequenceLength) return;
  dbc::LoopDetection message;
  message.match_id = next_match_id_++;
  message.query_frame = event.query_frame();
  message.sequence_length = static_cast<std::uint8_t>(k);
  message.match_frame = event.match_frame();
  message.match_score = event.score;
  // QueryTime is the capture time of the frame whose processing completed the
  // detection, so that (send stamp - QueryTime) is the end-to-end latency.
  message.query_time_s = seconds(current_frame_time_);
  message.match_time_s = std::max(0.0, event.match[event.framed].t);  // a loaded map's past: 0
  message.pose_valid = event.has_relative_pose;
  message.pose_dx_m = event.relative_pose.x;
  message.pose_dy_m = event.relative_pose.y;
  message.pose_dyaw_deg = event.relative_pose.yaw * kDegreesPerRadian;
  message.pose_residual_m = event.residual_m;
  ++counters_.loop_detections;
  bool first = true;
  for (const dbc::LoopPage page : dbc::LoopDetection::kPages) {
    message.loop_page = page;
    const Nanoseconds stamp = current_frame_time_ + (SteadyClock::now() - current_arrival_);
    if (first) detection_latency_.add(stamp - current_frame_time_);
    first = false;
    send(to_can(dbc::encode_frame(message, loop_sender_)), stamp);
  }
}

EcuFaults Ecu::faults(Nanoseconds now) noexcept {
  EcuFaults f;
  f.camera_lost = camera_lost_;
  f.camera_blind = camera_blind_ && !camera_lost_;
  f.odometry_timeout = !odometry_.pose_known(now);
  f.bus_error = bus_fault_ || bus_errors_in_cycle_ > 0 || odometry_.take_rejections() > 0;
  f.overrun = overruns_in_cycle_ > 0 || dropped_in_cycle_ > 0;
  return f;
}

void Ecu::send_status(Nanoseconds now) noexcept {
  const EcuFaults f = faults(now);
  last_faults_ = f;
  const DatabaseStats db = engine_.database().stats();
  dbc::Status status;
  if (counters_.frames_processed == 0 && !f.camera_lost)
    status.system_state = dbc::SystemState::Initialising;
  else if (f.camera_lost || f.camera_blind)
    status.system_state = dbc::SystemState::Fault;  // no road seen: no place recognition at all
  else if (f.odometry_timeout || f.bus_error || f.overrun)
    status.system_state = dbc::SystemState::Degraded;
  else
    status.system_state = dbc::SystemState::Running;
  status.fault_camera_lost = f.camera_lost;
  status.fault_camera_blind = f.camera_blind;
  status.frames_blind = saturate32(counters_.frames_blind);
  status.fault_odometry_timeout = f.odometry_timeout;
  status.fault_bus_error = f.bus_error;
  status.fault_overrun = f.overrun;
  status.frames_processed = saturate32(counters_.frames_processed);
  const double landmark_fill = double(db.landmarks) / double(std::max<std::size_t>(1, db.landmark_capacity));
  const double sequence_fill = double(db.sequences) / double(std::max<std::size_t>(1, db.sequence_capacity));
  status.database_fill_percent = 100.0 * std::max(landmark_fill, sequence_fill);
  status.frames_dropped =
      static_cast<std::uint32_t>(std::min<std::uint64_t>(counters_.frames_dropped, 0xFFFFFF));
  status.loop_time_max_ms = double(loop_time_max_ns_) / 1e6;
  status.landmark_count = static_cast<std::uint32_t>(std::min<std::size_t>(db.landmarks, 0xFFFFF));
  status.sequence_count = static_cast<std::uint32_t>(std::min<std::size_t>(db.sequences, 0xFFFFF));
  if (const std::optional<ScaleEstimate> scale = engine_.odometry_scale().estimate()) {
    status.odometry_scale_valid = true;
    status.odometry_scale = scale->scale;
    status.odometry_scale_error = scale->standard_error;
  }
  // A new cycle starts now: failures while sending these pages count in it.
  dropped_in_cycle_ = 0;
  overruns_in_cycle_ = 0;
  bus_errors_in_cycle_ = 0;
  loop_time_max_ns_ = 0;
  for (const dbc::StatusPage page : dbc::Status::kPages) {
    status.status_page = page;
    send(to_can(dbc::encode_frame(status, status_sender_)), now);
  }
  ++counters_.status_cycles;
}

void Ecu::finish(Nanoseconds now) noexcept {
  current_frame_time_ = now;
  current_arrival_ = SteadyClock::now();
  engine_.flush(*this);
}

}  // namespace markloop::ecu
