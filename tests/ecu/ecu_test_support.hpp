// Fakes and a synthetic drive for the ECU tests: a CAN sink that decodes what
// the ECU sends (no heap), a gateway that encodes odometry, and a loop road
// with markings whose detections a camera would report.
#pragma once

#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <span>
#include <system_error>

#include "app/ecu/ecu.hpp"
#include "app/perception/marking_detector.hpp"
#include "dbc/loop_detection_assembler.hpp"
#include "dbc/markloop_messages.hpp"
#include "drivers/can/can_frame.hpp"

namespace markloop::ecu::testing {

using namespace std::chrono_literals;

// Receives what the ECU sends, checks E2E like the SLAM back end would.
class RecordingBus final : public can::CanFrameSink {
 public:
  std::error_code refuse_with{};  // non-zero: every send fails with it (bus down, queue full)

  std::error_code send(const can::CanFrame& frame) noexcept override {
    if (refuse_with) return refuse_with;
    ++frames;
    last_stamp_ns = frame.timestamp_ns;
    if (frame.id == dbc::LoopDetection::kId) {
      dbc::LoopDetection page;
      if (dbc::decode(frame.payload(), loop_e2e, loop_page) != dbc::DecodeError::None) {
        ++errors;
        assembler.drop();
      } else if (assembler.add(loop_page)) {
        ++detections;
        last_detection = assembler.detection();
      }
      (void)page;
    } else if (frame.id == dbc::Status::kId) {
      if (dbc::decode(frame.payload(), status_e2e, status) != dbc::DecodeError::None)
        ++errors;
      else
        ++status_pages;
    } else {
      ++errors;
    }
    return {};
  }

  std::uint64_t frames = 0, errors = 0, detections = 0, status_pages = 0;
  std::int64_t last_stamp_ns = 0;
  dbc::E2eReceiverState loop_e2e, status_e2e;
  dbc::LoopDetection loop_page;
  dbc::LoopDetectionAssembler assembler;
  dbc::LoopDetection last_detection;
  dbc::Status status;  // pages accumulate
};

struct Gateway {
  dbc::E2eSenderState odometry_sender, command_sender;
  can::CanFrame odometry(double speed, double yaw_rate_rad) {
    dbc::VehicleOdometry m;
    m.wheel_speed_m_per_s = speed;
    m.yaw_rate_deg_per_s = yaw_rate_rad * 180.0 / std::numbers::pi;
    m.wheel_speed_valid = m.yaw_rate_valid = true;
    return to_can(dbc::encode_frame(m, odometry_sender));
  }
  can::CanFrame command(dbc::CommandCode code) {
    dbc::Command m;
    m.command_code = code;
    return to_can(dbc::encode_frame(m, command_sender));
  }
  static can::CanFrame to_can(const dbc::CanFrame& f) {
    can::CanFrame out;
    out.id = f.id;
    out.dlc = f.length;
    out.data = f.data;
    return out;
  }
};

// A circular road (1.2 km) with a marking every 14..26 m; the camera sees the
// markings 4..20 m ahead within 5 m of the centre line.
class LoopRoad {
 public:
  static constexpr double kLength = 1200.0;
  static constexpr double kRadius = kLength / (2 * std::numbers::pi);
  static constexpr double kSpeed = 10.0;
  static constexpr std::size_t kMaxMarkings = 128;

  LoopRoad() {
    std::uint32_t state = 12345;
    const auto next = [&] { return (state = state * 1664525u + 1013904223u) >> 8; };
    double s = 10.0;
    while (s < kLength - 20.0 && count_ < kMaxMarkings) {
      markings_[count_] = {s, (double(next() % 700) / 100.0) - 3.5, static_cast<Label>(next() % 16)};
      ++count_;
      s += 14.0 + double(next() % 1200) / 100.0;
    }
  }
  double yaw_rate() const { return kSpeed / kRadius; }
  // The car's true pose at time t (counter-clockwise circle from the origin).
  Pose2 pose(double t) const {
    const double a = kSpeed * t / kRadius;
    return {kRadius * std::sin(a), kRadius * (1 - std::cos(a)), a};
  }
  // Detections of the markings in view at time t; returns how many.
  std::size_t detections(double t, std::array<perception::Detection, perception::kMaxDetections>& out) const {
    const Pose2 car = pose(t);
    std::size_t n = 0;
    for (std::size_t i = 0; i < count_ && n < out.size(); ++i) {
      const double a = markings_[i].s / kRadius;
      const double r = kRadius - markings_[i].lateral;  // lateral: to the left (inside)
      const double wx = r * std::sin(a), wy = kRadius - r * std::cos(a);
      const double dx = wx - car.x, dy = wy - car.y;
      const double x = std::cos(car.yaw) * dx + std::sin(car.yaw) * dy;
      const double y = -std::sin(car.yaw) * dx + std::cos(car.yaw) * dy;
      if (x < 4.0 || x > 20.0 || std::abs(y) > 5.0) continue;
      perception::Detection d{};
      d.label = markings_[i].label;
      d.score = 0.9f;
      d.ground_x = static_cast<float>(x);
      d.ground_y = static_cast<float>(y);
      out[n++] = d;
    }
    return n;
  }

 private:
  struct Marking {
    double s, lateral;
    Label label;
  };
  std::array<Marking, kMaxMarkings> markings_{};
  std::size_t count_ = 0;
};

}  // namespace markloop::ecu::testing
