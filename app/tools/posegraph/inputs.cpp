#include "app/tools/posegraph/inputs.hpp"

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <string_view>

#include "app/common/units.hpp"
#include "app/tools/common/tool_files.hpp"
#include "app/tools/common/trajectory.hpp"
#include "app/tools/eval/can_log.hpp"
#include "app/tools/eval/inputs.hpp"
#include "app/tools/replay/paper_format.hpp"
#include "dbc/markloop_messages.hpp"
#include "drivers/can/candump_log.hpp"

namespace markloop::posegraph {

namespace {

using Nanoseconds = std::chrono::nanoseconds;

std::string where(const std::string& path, std::size_t line) {
  return path + ":" + std::to_string(line) + ": ";
}

Nanoseconds frame_time(std::size_t k, double fps) {
  return Nanoseconds(std::llround(static_cast<double>(k) / fps * 1e9));
}

// Advances the integrator through the frames stamped up to each frame
// time and samples the pose there, as the ECU's file mode does.
class FrameSampler {
 public:
  FrameSampler(double fps, OdometryTrack& out)
      : fps_(fps), out_(out), odometry_(std::chrono::milliseconds(std::lround(kOdometryTimeout_s * 1000))) {}

  void take(std::span<const std::uint8_t> payload, Nanoseconds stamp) {
    sample_until(stamp, false);
    odometry_.receive(payload, stamp);
  }
  // Every frame whose time is before `stamp` (or at it, when `inclusive`).
  void sample_until(Nanoseconds stamp, bool inclusive) {
    for (;;) {
      const Nanoseconds t = frame_time(out_.poses.size(), fps_);
      if (inclusive ? t > stamp : t >= stamp) return;
      if (!odometry_.pose_known(t)) ++out_.frames_without_pose;
      out_.poses.push_back(odometry_.pose_at(t));
    }
  }
  void finish() { out_.counters = odometry_.counters(); }

 private:
  double fps_;
  OdometryTrack& out_;
  ecu::OdometryIntegrator odometry_;
};

}  // namespace

Result<OdometryTrack> read_odometry_log(const std::string& path, double fps) {
  const Result<std::string> read = tools::read_input(path, eval::kMaxInputBytes, "a CAN log");
  if (!read) return read.error();
  OdometryTrack track;
  FrameSampler sampler(fps, track);
  tools::Lines lines(*read);
  std::string_view line;
  can::CandumpRecord record;
  Nanoseconds last{};
  bool any = false;
  while (lines.next(line)) {
    can::CandumpLineError problem;
    if (!can::parse_candump_line(line, record, problem))
      return error(where(path, lines.number()) + std::to_string(problem.column) + ": " + problem.what);
    const Nanoseconds stamp(record.frame.timestamp_ns);
    if (stamp < Nanoseconds{} || (any && stamp < last))
      return error(where(path, lines.number()) +
                   "stamp goes back in time (or before 0): the log must be on the "
                   "recording's clock, frame 0 at 0 s");
    if (record.frame.extended || record.frame.id != dbc::VehicleOdometry::kId) {
      ++track.other_frames;
      continue;
    }
    sampler.take(record.frame.payload(), stamp);
    last = stamp;
    any = true;
  }
  if (!read->empty() && read->back() != '\n')
    return error(where(path, lines.number()) +
                 "the last line is cut short: no newline at its end (was the log cut?)");
  if (!any) return error(path + ": no VehicleOdometry frame (id 0x120) in it");
  sampler.sample_until(last, true);
  sampler.finish();
  return track;
}

namespace {

Status check_frames(const std::string& path, std::size_t line, const LoopMeasurement& m,
                    std::size_t frame_count) {
  if (m.query < frame_count && m.match < frame_count) return {};
  return error(where(path, line) + "loop " + std::to_string(m.query) + " -> " + std::to_string(m.match) +
               " names a frame outside the recording (frames 0.." + std::to_string(frame_count - 1) +
               " by the odometry log)");
}

}  // namespace

Result<LoopInput> read_ecu_loops(const std::string& path, std::size_t frame_count) {
  Result<eval::EcuCanLog> log = eval::read_ecu_can_log(path);
  if (!log) return log.error();
  LoopInput input;
  input.incomplete = log->detections_incomplete;
  input.rejected_frames = log->loop_frames.rejected();
  const dbc::Status& status = log->status.last;
  if (log->status.page_seen[static_cast<std::size_t>(dbc::StatusPage::Odometry)] &&
      status.odometry_scale_valid)
    input.camera_scale = CameraScale{status.odometry_scale, status.odometry_scale_error};
  for (const eval::LoopReport& report : log->loops) {
    const dbc::LoopDetection& d = report.message;
    if (!d.pose_valid) {
      ++input.without_pose;
      continue;
    }
    const LoopMeasurement m{d.query_frame, d.match_frame,
                            Pose2{d.pose_dx_m, d.pose_dy_m, d.pose_dyaw_deg * kRadiansPerDegree},
                            d.pose_residual_m};
    if (Status inside = check_frames(path, report.line, m, frame_count); !inside) return inside.error();
    input.loops.push_back(m);
  }
  return input;
}

namespace {

// The number after "\"key\":" in a JSON line, searched from `from`.
std::optional<double> json_number(std::string_view line, std::string_view key, std::size_t from = 0) {
  // Appended piecewise: GCC 12 warns falsely (-Wrestrict) on a chain of +.
  std::string quoted(1, '"');
  quoted.append(key).append("\":");
  const std::size_t at = line.find(quoted, from);
  if (at == std::string_view::npos) return std::nullopt;
  const std::string rest(line.substr(at + quoted.size(), 40));
  char* end = nullptr;
  const double value = std::strtod(rest.c_str(), &end);
  if (end == rest.c_str() || !std::isfinite(value)) return std::nullopt;
  return value;
}

bool whole_frame(std::optional<double> v) {
  return v && *v >= 0 && *v <= 4294967295.0 && *v == std::floor(*v);
}

}  // namespace

Result<LoopInput> read_replay_jsonl(const std::string& path, std::size_t frame_count) {
  const Result<std::string> read = tools::read_input(path, eval::kMaxInputBytes, "a JSONL file");
  if (!read) return read.error();
  LoopInput input;
  tools::Lines lines(*read);
  std::string_view line;
  while (lines.next(line)) {
    if (line.find_first_not_of(" \t") == std::string_view::npos) continue;
    const auto query = json_number(line, "query_frame"), match = json_number(line, "match_frame");
    if (!line.starts_with("{") || !line.ends_with("}") || !whole_frame(query) || !whole_frame(match))
      return error(where(path, lines.number()) +
                   "expected a markloop-replay --jsonl record with query_frame and match_frame");
    const std::size_t pose_at = line.find("\"relative_pose\":{");
    if (pose_at == std::string_view::npos) {
      ++input.without_pose;
      continue;
    }
    const auto dx = json_number(line, "dx", pose_at), dy = json_number(line, "dy", pose_at),
               dyaw = json_number(line, "dyaw_deg", pose_at), residual = json_number(line, "residual_m");
    if (!dx || !dy || !dyaw || !residual || *residual < 0)
      return error(where(path, lines.number()) +
                   "relative_pose needs dx, dy, dyaw_deg and residual_m numbers");
    const LoopMeasurement m{static_cast<FrameIndex>(*query), static_cast<FrameIndex>(*match),
                            Pose2{*dx, *dy, *dyaw * kRadiansPerDegree}, *residual};
    if (Status inside = check_frames(path, lines.number(), m, frame_count); !inside) return inside.error();
    input.loops.push_back(m);
  }
  return input;
}

namespace {

// A TUM file's first pose line has 8 numbers; frames.csv and KITTI do not.
bool looks_like_tum(const std::string& path) {
  const Result<std::string> read = tools::read_input(path, std::size_t{512} << 20, "a truth file");
  if (!read) return false;
  tools::Lines lines(*read);
  std::string_view line;
  while (lines.next(line)) {
    const std::size_t start = line.find_first_not_of(" \t");
    if (start == std::string_view::npos || line[start] == '#') continue;
    std::size_t fields = 0;
    for (std::size_t i = start; i < line.size();) {
      const std::size_t end = line.find_first_of(" \t", i);
      ++fields;
      if (end == std::string_view::npos) break;
      i = line.find_first_not_of(" \t", end);
      if (i == std::string_view::npos) break;
    }
    return fields == 8;
  }
  return false;
}

}  // namespace

Result<Truth> load_truth(const std::string& path, double fps) {
  Truth truth;
  if (looks_like_tum(path)) {
    Result<std::vector<tools::TimedPose>> tum = tools::load_tum(path);
    if (!tum) return tum.error();
    for (const tools::TimedPose& p : *tum) {
      const double frame = std::round(p.t * fps);
      if (frame < 0 || frame > 1e8) return error(path + ": time " + std::to_string(p.t) + " s is no frame's");
      const auto k = static_cast<std::size_t>(frame);
      if (k >= truth.poses.size()) truth.poses.resize(k + 1), truth.known.resize(k + 1, false);
      truth.poses[k] = p.pose;
      truth.known[k] = true;
    }
    return truth;
  }
  Result<replay::TruePoses> loaded = replay::load_truth(path);
  if (!loaded) return loaded.error();
  truth.poses = std::move(loaded->poses);
  truth.known.assign(truth.poses.size(), true);
  return truth;
}

}  // namespace markloop::posegraph
