// The car's pose from VehicleOdometry: E2E-checked decoding (bad CRC, counter,
// length or range are counted and dropped), integration of speed and yaw
// rate (midpoint rule) and timeout supervision. While odometry is missing or
// invalid the pose is unknown, and the engine must not build sequences.
#pragma once

#include <chrono>
#include <cstdint>
#include <span>

#include "app/engine/types.hpp"
#include "dbc/markloop_messages.hpp"
#include "dbc/receive.hpp"

namespace markloop::ecu {

using Nanoseconds = std::chrono::nanoseconds;

struct OdometryCounters {
  std::uint64_t accepted = 0;
  std::uint64_t wrong_length = 0;
  std::uint64_t bad_crc = 0;
  std::uint64_t bad_counter = 0;
  std::uint64_t out_of_range = 0;
  std::uint64_t invalid_signals = 0;  // WheelSpeedValid or YawRateValid cleared
  std::uint64_t timeouts = 0;         // entries into the unknown-pose state
  std::uint64_t out_of_order = 0;     // stamps going backwards (dropped)
};

class OdometryIntegrator {
 public:
  explicit OdometryIntegrator(Nanoseconds timeout) : timeout_(timeout) {}

  // One VehicleOdometry payload received at `now`. Returns the decode result.
  dbc::DecodeError receive(std::span<const std::uint8_t> payload, Nanoseconds now) noexcept;

  // True while the last valid sample is at most `timeout` older than `now`.
  // Checks and counts the transition into timeout.
  bool pose_known(Nanoseconds now) noexcept;
  // The pose at `now`: the integrated pose, extrapolated from the last
  // sample with its speed and yaw rate. Meaningful only when pose_known(now).
  Pose2 pose_at(Nanoseconds now) const noexcept;

  const OdometryCounters& counters() const noexcept { return counters_; }
  // Rejected frames of any kind since the counter was last taken (for the
  // Status bus-error bit).
  std::uint64_t take_rejections() noexcept;

 private:
  void integrate(double speed, double yaw_rate, Nanoseconds now) noexcept;

  Nanoseconds timeout_;
  dbc::E2eReceiverState e2e_;
  bool have_sample_ = false;
  bool timed_out_ = true;
  Nanoseconds last_stamp_{};
  double last_speed_ = 0.0;     // m/s
  double last_yaw_rate_ = 0.0;  // rad/s
  Pose2 pose_{};
  OdometryCounters counters_;
  std::uint64_t rejections_ = 0;
};

}  // namespace markloop::ecu
