// Generated encoders/decoders: hand-worked wire vectors, round trips at the
// limits, saturation, rounding and rejection of untrustworthy frames.
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>

#include <catch2/catch_approx.hpp>
#include <catch2/catch_test_macros.hpp>

#include "dbc/markloop_messages.hpp"

using namespace markloop::dbc;
using Bytes = std::array<std::uint8_t, 8>;

namespace {

template <typename Message>
Bytes encoded(const Message& message, std::uint8_t counter = 0) {
  Bytes bytes{};
  const std::uint8_t length = encode(message, counter, std::span<std::uint8_t, 8>{bytes});
  REQUIRE(length == Message::kLength);
  return bytes;
}

template <typename Message>
Message round_trip(const Message& message) {
  const Bytes bytes = encoded(message);
  Message decoded{};
  REQUIRE(decode(std::span<const std::uint8_t>{bytes.data(), Message::kLength}, decoded) ==
          DecodeError::None);
  return decoded;
}

// Re-seals a payload that a test tampered with, so that only the intended
// check can fail.
template <typename Message>
void reseal(Bytes& bytes) {
  bytes[Message::kCrcByte] = e2e_crc(
      Message::kDataId, std::span<const std::uint8_t>{bytes.data(), Message::kLength}, Message::kCrcByte);
}

template <typename Message>
std::span<const std::uint8_t> payload_of(const Bytes& bytes) {
  return {bytes.data(), Message::kLength};
}

}  // namespace

// ---- wire layout constants --------------------------------------------------

static_assert(VehicleOdometry::kId == 0x120 && VehicleOdometry::kLength == 8);
static_assert(VehicleOdometry::kCycleTime == std::chrono::milliseconds{20});
static_assert(VehicleOdometry::kTimeout == std::chrono::milliseconds{60});
static_assert(Command::kId == 0x1A0 && Command::kLength == 4 && !Command::kIsCyclic);
static_assert(LoopDetection::kId == 0x2A0 && LoopDetection::kPages.size() == 6);
static_assert(Status::kId == 0x2B0 && Status::kCycleTime == std::chrono::milliseconds{100});
static_assert(Status::kPages.size() == 5);
static_assert(layout::loop_detection::kQueryFrame.length == 32 &&
              layout::loop_detection::kMatchFrame.length == 32);
static_assert(layout::vehicle_odometry::kWheelSpeed.order == ByteOrder::Motorola);
static_assert(kReceivedIds == std::array<std::uint32_t, 2>{0x120, 0x1A0});
static_assert(kSentIds == std::array<std::uint32_t, 2>{0x2A0, 0x2B0});
static_assert(message_name(0x2A0) == "LoopDetection" && message_name(0x7FF).empty());

// ---- byte-exact vectors -------------------------------------------------------

TEST_CASE("VehicleOdometry (Motorola) encodes to the hand-worked bytes") {
  // wheel speed 12.34 m/s  -> raw 1234 = 0x04D2; start bit 23 = byte 2 bit 7 is
  //   the MSB, big-endian: byte 2 = 0x04, byte 3 = 0xD2.
  // yaw rate -5 deg/s      -> raw -500 = 0xFE0C (16-bit two's complement);
  //   start bit 39 = byte 4 bit 7: byte 4 = 0xFE, byte 5 = 0x0C.
  // valid flags: bit 55 = byte 6 bit 7 (0x80), bit 54 = byte 6 bit 6 (0x40).
  // alive counter 3: start bit 11 = byte 1 bit 3, 4 bits down to bit 8: 0x03.
  // CRC over 01 51 (data id 0x5101, low byte first) 03 04 D2 FE 0C C0 00 = 0xF7
  //   (worked bit by bit: init 0xFF, poly 0x1D, xor-out 0xFF).
  VehicleOdometry odo;
  odo.wheel_speed_m_per_s = 12.34;
  odo.yaw_rate_deg_per_s = -5.0;
  odo.wheel_speed_valid = true;
  odo.yaw_rate_valid = true;
  CHECK(encoded(odo, 3) == Bytes{0xF7, 0x03, 0x04, 0xD2, 0xFE, 0x0C, 0xC0, 0x00});
}

TEST_CASE("Command (Intel, 4 bytes) encodes to the hand-worked bytes") {
  // counter 5 in byte 1 bits 0..3; SaveMap = 2 in byte 2; byte 3 unused;
  // CRC over 02 51 05 02 00 = 0xF9. Bytes 4..7 of the buffer stay zero.
  Command command;
  command.command_code = CommandCode::SaveMap;
  CHECK(encoded(command, 5) == Bytes{0xF9, 0x05, 0x02, 0x00, 0, 0, 0, 0});
}

TEST_CASE("LoopDetection page 4 (Intel, signed, multiplexed) encodes to the hand-worked bytes") {
  // byte 1: counter 0xA in bits 8..11, page 4 in bits 12..15 -> 0x4A.
  // byte 2: match id 0x7F.
  // dx -1.23 m -> raw -123 = 0xFF85, little-endian at bit 24: 85 FF.
  // dy  2.50 m -> raw  250 = 0x00FA at bit 40: FA 00.
  // pose valid: bit 56 -> byte 7 = 0x01.
  // CRC over 01 52 4A 7F 85 FF FA 00 01 = 0xBF.
  LoopDetection loop;
  loop.loop_page = LoopPage::Translation;
  loop.match_id = 0x7F;
  loop.pose_dx_m = -1.23;
  loop.pose_dy_m = 2.5;
  loop.pose_valid = true;
  loop.query_frame = 0xDEADBEEF;  // on page 0: must not leak into page 4
  CHECK(encoded(loop, 0xA) == Bytes{0xBF, 0x4A, 0x7F, 0x85, 0xFF, 0xFA, 0x00, 0x01});
}

TEST_CASE("Status page 2 (20-bit fields across byte boundaries) encodes to the hand-worked bytes") {
  // byte 1: counter 0xF, page 2 -> 0x2F.
  // byte 2: state Degraded = 2 in bits 16..19, odometry timeout bit 21 (0x20),
  //   overrun bit 23 (0x80) -> 0xA2.
  // landmarks 0x12345 at bits 24..43: byte 3 = 0x45, byte 4 = 0x23, byte 5
  //   low nibble = 0x1.
  // sequences 0xABCDE at bits 44..63: byte 5 high nibble = 0xE, byte 6 = 0xCD,
  //   byte 7 = 0xAB.
  // CRC over 02 52 2F A2 45 23 E1 CD AB = 0x21.
  Status status;
  status.status_page = StatusPage::Database;
  status.system_state = SystemState::Degraded;
  status.fault_odometry_timeout = true;
  status.fault_overrun = true;
  status.landmark_count = 0x12345;
  status.sequence_count = 0xABCDE;
  CHECK(encoded(status, 0xF) == Bytes{0x21, 0x2F, 0xA2, 0x45, 0x23, 0xE1, 0xCD, 0xAB});
}

TEST_CASE("Status page 3 (the camera's blindness) encodes to the hand-worked bytes") {
  // byte 1: counter 0x3, page 3 -> 0x33. byte 2: state Fault = 3 -> 0x03.
  // byte 3: FaultCameraBlind bit 24 -> 0x01, bits 25..31 unused.
  // FramesBlind 0x12345678 at bits 32..63, little-endian: 78 56 34 12.
  // CRC over 02 52 33 03 01 78 56 34 12 = 0x5F.
  Status status;
  status.status_page = StatusPage::Perception;
  status.system_state = SystemState::Fault;
  status.fault_camera_blind = true;
  status.frames_blind = 0x12345678;
  status.frames_processed = 0xFFFFFFFF;  // page 0's: must not leak into page 3
  CHECK(encoded(status, 0x3) == Bytes{0x5F, 0x33, 0x03, 0x01, 0x78, 0x56, 0x34, 0x12});
}

TEST_CASE("Status page 4 (the odometry's scale) encodes to the hand-worked bytes") {
  // byte 1: counter 0x5, page 4 -> 0x45. byte 2: state Running = 1 -> 0x01.
  // OdometryScale 0.99: (0.99 - 1) / 0.00001 = -1000 = 0xFC18 at bits 24..39,
  //   little-endian: 18 FC. OdometryScaleError 0.00123 -> 123: 7B 00.
  // OdometryScaleValid bit 56 -> byte 7 = 0x01.
  // CRC over 02 52 45 01 18 FC 7B 00 01 = 0x33.
  Status status;
  status.status_page = StatusPage::Odometry;
  status.system_state = SystemState::Running;
  status.odometry_scale = 0.99;
  status.odometry_scale_error = 0.00123;
  status.odometry_scale_valid = true;
  CHECK(encoded(status, 0x5) == Bytes{0x33, 0x45, 0x01, 0x18, 0xFC, 0x7B, 0x00, 0x01});
}

// ---- round trips ----------------------------------------------------------------

TEST_CASE("VehicleOdometry round-trips at its limits, saturates beyond, rounds to 0.01") {
  VehicleOdometry odo;
  SECTION("limits") {
    for (const double speed : {-100.0, 0.0, 100.0, -0.01, 0.01}) {
      odo.wheel_speed_m_per_s = speed;
      odo.yaw_rate_deg_per_s = -speed * 3.0;
      const VehicleOdometry back = round_trip(odo);
      CHECK(back.wheel_speed_m_per_s == Catch::Approx(speed).margin(1e-9));
      CHECK(back.yaw_rate_deg_per_s == Catch::Approx(-speed * 3.0).margin(1e-9));
    }
  }
  SECTION("just beyond the range saturates") {
    odo.wheel_speed_m_per_s = 100.01;
    odo.yaw_rate_deg_per_s = -300.01;
    VehicleOdometry back = round_trip(odo);
    CHECK(back.wheel_speed_m_per_s == Catch::Approx(100.0));
    CHECK(back.yaw_rate_deg_per_s == Catch::Approx(-300.0));
    odo.wheel_speed_m_per_s = -1e9;
    odo.yaw_rate_deg_per_s = std::numeric_limits<double>::infinity();
    back = round_trip(odo);
    CHECK(back.wheel_speed_m_per_s == Catch::Approx(-100.0));
    CHECK(back.yaw_rate_deg_per_s == Catch::Approx(300.0));
  }
  SECTION("NaN encodes as the minimum") {
    odo.wheel_speed_m_per_s = std::numeric_limits<double>::quiet_NaN();
    CHECK(round_trip(odo).wheel_speed_m_per_s == Catch::Approx(-100.0));
  }
  SECTION("rounding to the nearest step, halves away from zero") {
    odo.wheel_speed_m_per_s = 1.234;  // 123.4 -> 123
    CHECK(round_trip(odo).wheel_speed_m_per_s == Catch::Approx(1.23));
    odo.wheel_speed_m_per_s = 1.236;  // 123.6 -> 124
    CHECK(round_trip(odo).wheel_speed_m_per_s == Catch::Approx(1.24));
    odo.wheel_speed_m_per_s = -1.236;  // -123.6 -> -124
    CHECK(round_trip(odo).wheel_speed_m_per_s == Catch::Approx(-1.24));
    odo.wheel_speed_m_per_s = 0.125;  // 12.5 exactly -> 13
    CHECK(round_trip(odo).wheel_speed_m_per_s == Catch::Approx(0.13));
    odo.wheel_speed_m_per_s = -0.125;  // -12.5 -> -13
    CHECK(round_trip(odo).wheel_speed_m_per_s == Catch::Approx(-0.13));
  }
  SECTION("flags") {
    odo.wheel_speed_valid = true;
    CHECK(round_trip(odo).wheel_speed_valid);
    CHECK_FALSE(round_trip(odo).yaw_rate_valid);
  }
}

TEST_CASE("Command round-trips both codes and saturates an undefined enum value") {
  Command command;
  command.command_code = CommandCode::ResetDatabase;
  CHECK(round_trip(command).command_code == CommandCode::ResetDatabase);
  command.command_code = CommandCode::SaveMap;
  CHECK(round_trip(command).command_code == CommandCode::SaveMap);
  command.command_code = static_cast<CommandCode>(7);
  CHECK(round_trip(command).command_code == CommandCode::SaveMap);
}

TEST_CASE("LoopDetection round-trips every page and accumulates pages into one struct") {
  LoopDetection sent;
  sent.match_id = 200;
  sent.query_frame = 4294967295U;
  sent.sequence_length = 10;
  sent.match_frame = 123456;
  sent.match_score = 0.5;
  sent.query_time_s = 4294967.295;
  sent.match_time_s = 12.345;
  sent.pose_dx_m = -300.0;
  sent.pose_dy_m = 300.0;
  sent.pose_valid = true;
  sent.pose_dyaw_deg = -179.99;
  sent.pose_residual_m = 0.123;

  LoopDetection received;
  E2eReceiverState e2e;
  E2eSenderState sender;
  for (const LoopPage page : LoopDetection::kPages) {
    sent.loop_page = page;
    const CanFrame frame = encode_frame(sent, sender);
    REQUIRE(frame.id == LoopDetection::kId);
    REQUIRE(frame.length == 8);
    REQUIRE(decode(std::span<const std::uint8_t>{frame.data.data(), frame.length}, e2e, received) ==
            DecodeError::None);
    CHECK(received.loop_page == page);
  }
  CHECK(received.match_id == 200);
  CHECK(received.query_frame == 4294967295U);
  CHECK(received.sequence_length == 10);
  CHECK(received.match_frame == 123456);
  CHECK(received.match_score == Catch::Approx(0.5));
  CHECK(received.query_time_s == Catch::Approx(4294967.295).margin(1e-6));
  CHECK(received.match_time_s == Catch::Approx(12.345).margin(1e-9));
  CHECK(received.pose_dx_m == Catch::Approx(-300.0));
  CHECK(received.pose_dy_m == Catch::Approx(300.0));
  CHECK(received.pose_valid);
  CHECK(received.pose_dyaw_deg == Catch::Approx(-179.99));
  CHECK(received.pose_residual_m == Catch::Approx(0.123));
}

TEST_CASE("LoopDetection saturates to its ranges") {
  LoopDetection loop;
  loop.loop_page = LoopPage::Query;
  loop.sequence_length = 0;  // below min 1
  CHECK(round_trip(loop).sequence_length == 1);
  loop.sequence_length = 200;  // above max 16
  CHECK(round_trip(loop).sequence_length == 16);
  loop.loop_page = LoopPage::Match;
  loop.match_score = 1.5;
  CHECK(round_trip(loop).match_score == Catch::Approx(1.0));
  loop.match_score = -0.1;
  CHECK(round_trip(loop).match_score == Catch::Approx(0.0));
  loop.loop_page = LoopPage::QueryTime;
  loop.query_time_s = -1.0;
  CHECK(round_trip(loop).query_time_s == Catch::Approx(0.0));
  loop.query_time_s = 5e6;
  CHECK(round_trip(loop).query_time_s == Catch::Approx(4294967.295));
  loop.loop_page = LoopPage::Translation;
  loop.pose_dx_m = 300.004;   // rounds onto the maximum
  loop.pose_dy_m = -300.006;  // beyond: saturates
  LoopDetection back = round_trip(loop);
  CHECK(back.pose_dx_m == Catch::Approx(300.0));
  CHECK(back.pose_dy_m == Catch::Approx(-300.0));
  loop.loop_page = LoopPage::RotationResidual;
  loop.pose_dyaw_deg = 180.5;
  loop.pose_residual_m = 100.0;
  back = round_trip(loop);
  CHECK(back.pose_dyaw_deg == Catch::Approx(180.0));
  CHECK(back.pose_residual_m == Catch::Approx(65.535));
}

TEST_CASE("Status round-trips every page with state and flags on each") {
  Status sent;
  sent.system_state = SystemState::Fault;
  sent.fault_camera_lost = true;
  sent.fault_bus_error = true;
  sent.frames_processed = 4294967295U;
  sent.database_fill_percent = 99.74;  // -> 199.48 -> 199 -> 99.5
  sent.frames_dropped = 16777216;      // one beyond 24 bits: saturates
  sent.loop_time_max_ms = 12.345;      // -> 1234.5 -> 1235 -> 12.35
  sent.landmark_count = 1048576;       // one beyond 20 bits: saturates
  sent.sequence_count = 0;
  sent.fault_camera_blind = true;
  sent.frames_blind = 4294967295U;
  sent.odometry_scale = 1.004567;   // -> 456.7 -> 457 -> 1.00457
  sent.odometry_scale_error = 0.7;  // beyond 16 bits: saturates
  sent.odometry_scale_valid = true;

  Status received;
  for (const StatusPage page : Status::kPages) {
    sent.status_page = page;
    const Bytes bytes = encoded(sent);
    REQUIRE(decode(payload_of<Status>(bytes), received) == DecodeError::None);
    CHECK(received.system_state == SystemState::Fault);
    CHECK(received.fault_camera_lost);
    CHECK_FALSE(received.fault_odometry_timeout);
    CHECK(received.fault_bus_error);
    CHECK_FALSE(received.fault_overrun);
  }
  CHECK(received.frames_processed == 4294967295U);
  CHECK(received.database_fill_percent == Catch::Approx(99.5));
  CHECK(received.frames_dropped == 16777215);
  CHECK(received.loop_time_max_ms == Catch::Approx(12.35));
  CHECK(received.landmark_count == 1048575);
  CHECK(received.sequence_count == 0);
  CHECK(received.fault_camera_blind);
  CHECK(received.frames_blind == 4294967295U);
  CHECK(received.odometry_scale == Catch::Approx(1.00457));
  CHECK(received.odometry_scale_error == Catch::Approx(0.65535));
  CHECK(received.odometry_scale_valid);
}

// ---- rejection --------------------------------------------------------------------

TEST_CASE("decode rejects a wrong length, before looking at anything else") {
  VehicleOdometry odo;
  const Bytes bytes = encoded(odo);
  VehicleOdometry out;
  CHECK(decode(std::span<const std::uint8_t>{bytes.data(), 7}, out) == DecodeError::WrongLength);
  CHECK(decode(std::span<const std::uint8_t>{}, out) == DecodeError::WrongLength);
  const Bytes command = encoded(Command{});
  Command command_out;
  CHECK(decode(std::span<const std::uint8_t>{command.data(), 8}, command_out) == DecodeError::WrongLength);
  CHECK(decode(std::span<const std::uint8_t>{command.data(), 4}, command_out) == DecodeError::None);
}

TEST_CASE("decode rejects any single flipped bit by CRC, and a frame meant for another id") {
  VehicleOdometry odo;
  odo.wheel_speed_m_per_s = 3.0;
  const Bytes good = encoded(odo, 1);
  for (std::size_t bit = 0; bit < 64; ++bit) {
    Bytes bad = good;
    bad[bit / 8] = static_cast<std::uint8_t>(bad[bit / 8] ^ (1U << (bit % 8)));
    VehicleOdometry out;
    CHECK(decode(payload_of<VehicleOdometry>(bad), out) == DecodeError::BadCrc);
  }
  // Same layout, other data id: an Status frame is no LoopDetection frame.
  Status status;
  const Bytes status_bytes = encoded(status);
  LoopDetection loop;
  CHECK(decode(payload_of<LoopDetection>(status_bytes), loop) == DecodeError::BadCrc);
}

TEST_CASE("decode leaves the output untouched on any error") {
  VehicleOdometry out;
  out.wheel_speed_m_per_s = 42.0;
  Bytes bytes = encoded(VehicleOdometry{});
  bytes[3] ^= 0x01;
  CHECK(decode(payload_of<VehicleOdometry>(bytes), out) == DecodeError::BadCrc);
  CHECK(out.wheel_speed_m_per_s == 42.0);
}

TEST_CASE("decode rejects raw values outside the DBC range or value table") {
  SECTION("yaw rate raw above max (30001 = 300.01 deg/s)") {
    Bytes bytes = encoded(VehicleOdometry{});
    bytes[4] = 0x75;  // 0x7531 = 30001, big-endian
    bytes[5] = 0x31;
    reseal<VehicleOdometry>(bytes);
    VehicleOdometry out;
    CHECK(decode(payload_of<VehicleOdometry>(bytes), out) == DecodeError::OutOfRange);
    bytes[5] = 0x30;  // 30000 is the maximum itself
    reseal<VehicleOdometry>(bytes);
    CHECK(decode(payload_of<VehicleOdometry>(bytes), out) == DecodeError::None);
    CHECK(out.yaw_rate_deg_per_s == Catch::Approx(300.0));
  }
  SECTION("command code 0 and 3 are undefined") {
    Command out;
    for (const std::uint8_t code : {std::uint8_t{0}, std::uint8_t{3}, std::uint8_t{255}}) {
      Bytes bytes = encoded(Command{});
      bytes[2] = code;
      reseal<Command>(bytes);
      CHECK(decode(payload_of<Command>(bytes), out) == DecodeError::OutOfRange);
    }
  }
  SECTION("system state 4 is undefined") {
    Bytes bytes = encoded(Status{});
    bytes[2] = static_cast<std::uint8_t>((bytes[2] & 0xF0) | 0x04);
    reseal<Status>(bytes);
    Status out;
    CHECK(decode(payload_of<Status>(bytes), out) == DecodeError::OutOfRange);
  }
  SECTION("sequence length 0 and 17 are outside [1, 16]") {
    LoopDetection loop;
    loop.loop_page = LoopPage::Query;
    LoopDetection out;
    for (const std::uint8_t k : {std::uint8_t{0}, std::uint8_t{17}}) {
      Bytes bytes = encoded(loop);
      bytes[7] = k;
      reseal<LoopDetection>(bytes);
      CHECK(decode(payload_of<LoopDetection>(bytes), out) == DecodeError::OutOfRange);
    }
  }
  SECTION("match score raw 251 is above 1.0") {
    LoopDetection loop;
    loop.loop_page = LoopPage::Match;
    Bytes bytes = encoded(loop);
    bytes[7] = 251;
    reseal<LoopDetection>(bytes);
    LoopDetection out;
    CHECK(decode(payload_of<LoopDetection>(bytes), out) == DecodeError::OutOfRange);
  }
  SECTION("dyaw raw -18001 is below -180 deg") {
    LoopDetection loop;
    loop.loop_page = LoopPage::RotationResidual;
    Bytes bytes = encoded(loop);
    bytes[3] = 0xAF;  // -18001 = 0xB9AF, little-endian
    bytes[4] = 0xB9;
    reseal<LoopDetection>(bytes);
    LoopDetection out;
    CHECK(decode(payload_of<LoopDetection>(bytes), out) == DecodeError::OutOfRange);
  }
}

TEST_CASE("decode rejects a page the DBC does not define") {
  for (const std::uint8_t page : {std::uint8_t{6}, std::uint8_t{15}}) {
    Bytes bytes = encoded(LoopDetection{});
    bytes[1] = static_cast<std::uint8_t>((bytes[1] & 0x0F) | (page << 4));
    reseal<LoopDetection>(bytes);
    LoopDetection out;
    CHECK(decode(payload_of<LoopDetection>(bytes), out) == DecodeError::UnknownPage);
  }
  Bytes bytes = encoded(Status{});
  bytes[1] = static_cast<std::uint8_t>((bytes[1] & 0x0F) | (5 << 4));
  reseal<Status>(bytes);
  Status out;
  CHECK(decode(payload_of<Status>(bytes), out) == DecodeError::UnknownPage);
}
