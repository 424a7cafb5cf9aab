// Odometry: E2E-checked decoding, midpoint integration, timeout.
#include <catch2/catch_approx.hpp>
#include <catch2/catch_test_macros.hpp>

#include <array>
#include <chrono>
#include <cmath>
#include <numbers>

#include "app/ecu/odometry.hpp"
#include "dbc/markloop_messages.hpp"

using namespace markloop;
using namespace std::chrono_literals;
using ecu::Nanoseconds;

namespace {

struct Gateway {
  dbc::E2eSenderState sender;
  std::array<std::uint8_t, 8> payload(double speed, double yaw_rate_deg, bool valid = true) {
    dbc::VehicleOdometry m;
    m.wheel_speed_m_per_s = speed;
    m.yaw_rate_deg_per_s = yaw_rate_deg;
    m.wheel_speed_valid = valid;
    m.yaw_rate_valid = valid;
    std::array<std::uint8_t, 8> out{};
    dbc::encode(m, sender.next(), std::span<std::uint8_t, 8>(out));
    return out;
  }
};

}  // namespace

TEST_CASE("constant speed and yaw rate integrate to the exact circle") {
  ecu::OdometryIntegrator odo(60ms);
  Gateway gw;
  const double speed = 10.0, yaw_rate_deg = 9.0;  // radius 63.66 m
  Nanoseconds t{0};
  for (int i = 0; i <= 500; ++i, t += 20ms)  // 10 s
    REQUIRE(odo.receive(gw.payload(speed, yaw_rate_deg), t) == dbc::DecodeError::None);
  t -= 20ms;
  REQUIRE(odo.pose_known(t));
  const double w = yaw_rate_deg * std::numbers::pi / 180.0, T = 10.0, r = speed / w;
  const Pose2 p = odo.pose_at(t);
  CHECK(p.x == Catch::Approx(r * std::sin(w * T)).margin(1e-6));
  CHECK(p.y == Catch::Approx(r * (1 - std::cos(w * T))).margin(1e-6));
  CHECK(p.yaw == Catch::Approx(wrap_angle(w * T)).margin(1e-9));
  // Extrapolation between samples follows the same circle.
  const Pose2 q = odo.pose_at(t + 10ms);
  CHECK(q.x == Catch::Approx(r * std::sin(w * (T + 0.01))).margin(1e-6));
  CHECK(odo.counters().accepted == 501);
}

TEST_CASE("bad CRC, skipped or repeated counter and wrong length are counted and dropped") {
  ecu::OdometryIntegrator odo(60ms);
  Gateway gw;
  REQUIRE(odo.receive(gw.payload(10, 0), 0ms) == dbc::DecodeError::None);
  auto corrupted = gw.payload(10, 0);
  corrupted[5] ^= 0x01;
  CHECK(odo.receive(corrupted, 20ms) == dbc::DecodeError::BadCrc);
  // The corrupted frame took a counter value: the next one looks skipped
  // (E2E: rejected, resynchronised), the one after is accepted.
  CHECK(odo.receive(gw.payload(10, 0), 40ms) == dbc::DecodeError::BadCounter);
  auto good = gw.payload(10, 0);
  CHECK(odo.receive(good, 60ms) == dbc::DecodeError::None);
  CHECK(odo.receive(good, 80ms) == dbc::DecodeError::BadCounter);  // same counter again
  CHECK(odo.receive(std::span<const std::uint8_t>(good.data(), 5), 80ms) == dbc::DecodeError::WrongLength);
  CHECK(odo.counters().bad_crc == 1);
  CHECK(odo.counters().bad_counter == 2);
  CHECK(odo.counters().wrong_length == 1);
  CHECK(odo.counters().accepted == 2);
  CHECK(odo.take_rejections() == 4);
  CHECK(odo.take_rejections() == 0);
  // The rejected frames did not move the car, and the accepted ones 60 ms
  // apart were integrated (at most the timeout): 0.6 m.
  CHECK(odo.pose_at(60ms).x == Catch::Approx(0.6));
}

TEST_CASE("odometry timeout makes the pose unknown until frames come back") {
  ecu::OdometryIntegrator odo(60ms);
  Gateway gw;
  CHECK_FALSE(odo.pose_known(0ms));  // nothing yet
  for (int i = 0; i < 10; ++i) odo.receive(gw.payload(5, 0), i * 20ms);
  CHECK(odo.pose_known(180ms + 60ms));
  CHECK_FALSE(odo.pose_known(180ms + 61ms));
  CHECK(odo.counters().timeouts == 1);
  CHECK_FALSE(odo.pose_known(500ms));
  CHECK(odo.counters().timeouts == 1);  // counted once per loss
  // The gateway restarted (counter from 0 again): accepted after a timeout.
  Gateway restarted;
  CHECK(odo.receive(restarted.payload(5, 0), 1000ms) == dbc::DecodeError::None);
  CHECK(odo.pose_known(1000ms));
  // The gap was not integrated: the pose continues from where it was.
  CHECK(odo.pose_at(1000ms).x == Catch::Approx(0.9));
}

TEST_CASE("frames flagged invalid do not advance the pose or feed the timeout") {
  ecu::OdometryIntegrator odo(60ms);
  Gateway gw;
  odo.receive(gw.payload(10, 0), 0ms);
  odo.receive(gw.payload(10, 0, false), 20ms);
  odo.receive(gw.payload(10, 0, false), 40ms);
  CHECK(odo.counters().invalid_signals == 2);
  CHECK(odo.pose_known(60ms));
  CHECK_FALSE(odo.pose_known(80ms));
}
