#include "app/ecu/odometry.hpp"
#include "app/common/units.hpp"

#include <cmath>
#include <numbers>

namespace markloop::ecu {

namespace {
double seconds(Nanoseconds d) {
  return std::chrono::duration<double>(d).count();
}
}  // namespace

dbc::DecodeError OdometryIntegrator::receive(std::span<const std::uint8_t> payload,
                                             Nanoseconds now) noexcept {
  // After a timeout the gateway may have restarted: accept its next counter.
  if (!have_sample_ || now - last_stamp_ > timeout_) e2e_.reset();
  dbc::VehicleOdometry message;
  const dbc::DecodeError error = dbc::decode(payload, e2e_, message);
  switch (error) {
    case dbc::DecodeError::None:
      break;
    case dbc::DecodeError::WrongLength:
      ++counters_.wrong_length;
      break;
    case dbc::DecodeError::BadCrc:
      ++counters_.bad_crc;
      break;
    case dbc::DecodeError::BadCounter:
      ++counters_.bad_counter;
      break;
    case dbc::DecodeError::OutOfRange:
    case dbc::DecodeError::UnknownPage:
      ++counters_.out_of_range;
      break;
  }
  if (error != dbc::DecodeError::None) {
    ++rejections_;
    return error;
  }
  if (have_sample_ && now < last_stamp_) {
    ++counters_.out_of_order;
    ++rejections_;
    return error;
  }
  if (!message.wheel_speed_valid || !message.yaw_rate_valid) {
    // A valid frame with invalid signals: the pose cannot be advanced, so
    // the sample does not feed the timeout either.
    ++counters_.invalid_signals;
    return error;
  }
  ++counters_.accepted;
  integrate(message.wheel_speed_m_per_s, message.yaw_rate_deg_per_s * kRadiansPerDegree, now);
  return error;
}

void OdometryIntegrator::integrate(double speed, double yaw_rate, Nanoseconds now) noexcept {
  if (have_sample_ && now - last_stamp_ <= timeout_) {
    // Midpoint rule: mean speed and yaw rate over the interval, heading at
    // its middle.
    const double dt = seconds(now - last_stamp_);
    const double mean_speed = 0.5 * (speed + last_speed_);
    const double mean_yaw_rate = 0.5 * (yaw_rate + last_yaw_rate_);
    const double mid_yaw = pose_.yaw + 0.5 * mean_yaw_rate * dt;
    pose_.x += mean_speed * std::cos(mid_yaw) * dt;
    pose_.y += mean_speed * std::sin(mid_yaw) * dt;
    pose_.yaw = wrap_angle(pose_.yaw + mean_yaw_rate * dt);
  }
  // After a gap the pose restarts from where it was: the world frame shifts
  // by whatever the car did unobserved, which is why sequences break there.
  have_sample_ = true;
  last_stamp_ = now;
  last_speed_ = speed;
  last_yaw_rate_ = yaw_rate;
}

bool OdometryIntegrator::pose_known(Nanoseconds now) noexcept {
  const bool known = have_sample_ && now - last_stamp_ <= timeout_;
  if (!known && !timed_out_) ++counters_.timeouts;
  timed_out_ = !known;
  return known;
}

Pose2 OdometryIntegrator::pose_at(Nanoseconds now) const noexcept {
  if (!have_sample_ || now <= last_stamp_) return pose_;
  const double dt = seconds(now - last_stamp_);
  const double mid_yaw = pose_.yaw + 0.5 * last_yaw_rate_ * dt;
  return {pose_.x + last_speed_ * std::cos(mid_yaw) * dt, pose_.y + last_speed_ * std::sin(mid_yaw) * dt,
          wrap_angle(pose_.yaw + last_yaw_rate_ * dt)};
}

std::uint64_t OdometryIntegrator::take_rejections() noexcept {
  const std::uint64_t n = rejections_;
  rejections_ = 0;
  return n;
}

}  // namespace markloop::ecu
