// Alive counter policy, receive timeout, the per-message Receiver and the
// LoopDetection page assembler.
#include <array>
#include <chrono>
#include <cstdint>
#include <span>

#include <catch2/catch_test_macros.hpp>

#include "dbc/loop_detection_assembler.hpp"
#include "dbc/markloop_messages.hpp"

using namespace markloop::dbc;
using namespace std::chrono_literals;

namespace {

CanFrame odometry_frame(std::uint8_t counter) {
  VehicleOdometry odo;
  odo.wheel_speed_m_per_s = 10.0;
  CanFrame frame;
  frame.id = VehicleOdometry::kId;
  frame.length = encode(odo, counter, std::span<std::uint8_t, 8>{frame.data});
  return frame;
}

std::span<const std::uint8_t> payload(const CanFrame& frame) {
  return {frame.data.data(), frame.length};
}

}  // namespace

TEST_CASE("E2E receiver: first frame accepted, then only +1, wrapping 15 -> 0") {
  E2eReceiverState e2e;
  CHECK_FALSE(e2e.synchronised());
  CHECK(e2e.accept(9));  // first after start: any counter
  CHECK(e2e.accept(10));
  for (std::uint8_t c = 11; c < 16; ++c) CHECK(e2e.accept(c));
  CHECK(e2e.accept(0));  // wrap
  CHECK(e2e.accept(1));
}

TEST_CASE("E2E receiver rejects a repeated counter without moving") {
  E2eReceiverState e2e;
  REQUIRE(e2e.accept(4));
  CHECK_FALSE(e2e.accept(4));
  CHECK_FALSE(e2e.accept(4));
  CHECK(e2e.accept(5));
}

TEST_CASE("E2E receiver rejects a skipped counter and resynchronises on it") {
  E2eReceiverState e2e;
  REQUIRE(e2e.accept(14));
  CHECK_FALSE(e2e.accept(0));  // 15 was lost
  CHECK(e2e.accept(1));        // in sequence again
  CHECK_FALSE(e2e.accept(0));  // going back is a skip of 15 too
  e2e.reset();
  CHECK(e2e.accept(7));  // after reset anything is accepted again
}

TEST_CASE("decode with E2E state: repeated, skipped, wrapped counters") {
  E2eReceiverState e2e;
  VehicleOdometry out;
  CHECK(decode(payload(odometry_frame(15)), e2e, out) == DecodeError::None);
  CHECK(decode(payload(odometry_frame(0)), e2e, out) == DecodeError::None);        // 15 -> 0
  CHECK(decode(payload(odometry_frame(0)), e2e, out) == DecodeError::BadCounter);  // repeated
  CHECK(decode(payload(odometry_frame(2)), e2e, out) == DecodeError::BadCounter);  // 1 skipped
  CHECK(decode(payload(odometry_frame(3)), e2e, out) == DecodeError::None);
  // A corrupted frame does not disturb the counter state.
  CanFrame corrupt = odometry_frame(4);
  corrupt.data[3] ^= 0x10;
  CHECK(decode(payload(corrupt), e2e, out) == DecodeError::BadCrc);
  CHECK(decode(payload(odometry_frame(4)), e2e, out) == DecodeError::None);
  // Without state (logs) the counter is not checked.
  CHECK(decode(payload(odometry_frame(4)), out) == DecodeError::None);
}

TEST_CASE("sender counter counts 0..15 and wraps") {
  E2eSenderState sender;
  for (unsigned i = 0; i < 40; ++i) CHECK(sender.next() == i % 16);
}

TEST_CASE("receive timeout: flag after more than the timeout, cleared by reception") {
  ReceiveTimeout timeout{VehicleOdometry::kTimeout};
  CHECK(timeout.timed_out(0ms));  // nothing received yet
  timeout.start(1000ms);
  CHECK_FALSE(timeout.timed_out(1060ms));  // exactly 3 cycles: still fine
  CHECK(timeout.timed_out(1060ms + 1ns));
  timeout.on_received(1070ms);
  CHECK_FALSE(timeout.timed_out(1100ms));
  CHECK(timeout.timed_out(1131ms));
  timeout.reset();
  CHECK(timeout.timed_out(1070ms));
}

TEST_CASE("Receiver: times out without valid frames, resyncs the counter after a timeout") {
  Receiver<VehicleOdometry> receiver;
  VehicleOdometry out;
  CHECK(receiver.timed_out(0ms));
  CHECK(receiver.receive(payload(odometry_frame(5)), 0ms, out) == DecodeError::None);
  CHECK(out.wheel_speed_m_per_s == 10.0);
  CHECK_FALSE(receiver.timed_out(20ms));
  CHECK(receiver.receive(payload(odometry_frame(6)), 20ms, out) == DecodeError::None);

  // Only bad frames for a while: they do not keep the message alive.
  CanFrame corrupt = odometry_frame(7);
  corrupt.data[2] ^= 0x01;
  CHECK(receiver.receive(payload(corrupt), 40ms, out) == DecodeError::BadCrc);
  CHECK(receiver.receive(payload(odometry_frame(6)), 60ms, out) == DecodeError::BadCounter);
  CHECK_FALSE(receiver.timed_out(80ms));
  CHECK(receiver.timed_out(81ms));

  // After the timeout the sender may have restarted: its counter is taken as is.
  CHECK(receiver.receive(payload(odometry_frame(0)), 100ms, out) == DecodeError::None);
  CHECK_FALSE(receiver.timed_out(100ms));
  CHECK(receiver.receive(payload(odometry_frame(2)), 120ms, out) == DecodeError::BadCounter);
  CHECK(receiver.accepted() == 3);
  CHECK(receiver.rejected() == 3);
}

TEST_CASE("Receiver of an event message never times out and keeps its counter") {
  Receiver<Command> receiver;
  Command out;
  CHECK_FALSE(receiver.timed_out(0ms));
  Command command;
  command.command_code = CommandCode::SaveMap;
  E2eSenderState sender;
  const CanFrame first = encode_frame(command, sender);
  CHECK(receiver.receive(payload(first), 0ms, out) == DecodeError::None);
  CHECK(out.command_code == CommandCode::SaveMap);
  CHECK_FALSE(receiver.timed_out(1h));
  // A replay of the same frame an hour later is still a repeated counter.
  CHECK(receiver.receive(payload(first), 1h, out) == DecodeError::BadCounter);
  CHECK(receiver.receive(payload(encode_frame(command, sender)), 1h, out) == DecodeError::None);
}

namespace {

std::array<CanFrame, 6> loop_frames(std::uint8_t match_id, std::uint32_t query_frame,
                                    E2eSenderState& sender) {
  LoopDetection loop;
  loop.match_id = match_id;
  loop.query_frame = query_frame;
  loop.match_frame = query_frame / 2;
  loop.pose_dx_m = 1.5;
  loop.pose_residual_m = 0.02;
  std::array<CanFrame, 6> frames{};
  for (std::size_t i = 0; i < LoopDetection::kPages.size(); ++i) {
    loop.loop_page = LoopDetection::kPages[i];
    frames[i] = encode_frame(loop, sender);
  }
  return frames;
}

// What a receiver does per frame: decode into a fresh struct, feed or drop.
bool feed(LoopDetectionAssembler& assembler, E2eReceiverState& e2e, const CanFrame& frame) {
  LoopDetection page;
  if (decode(payload(frame), e2e, page) != DecodeError::None) {
    assembler.drop();
    return false;
  }
  return assembler.add(page);
}

}  // namespace

TEST_CASE("LoopDetectionAssembler completes a detection from its six pages") {
  E2eSenderState sender;
  E2eReceiverState e2e;
  LoopDetectionAssembler assembler;
  const auto frames = loop_frames(9, 5000, sender);
  for (std::size_t i = 0; i + 1 < frames.size(); ++i) CHECK_FALSE(feed(assembler, e2e, frames[i]));
  REQUIRE(feed(assembler, e2e, frames.back()));
  const LoopDetection& detection = assembler.detection();
  CHECK(detection.match_id == 9);
  CHECK(detection.query_frame == 5000);
  CHECK(detection.match_frame == 2500);
  CHECK(detection.pose_dx_m == 1.5);
  CHECK(detection.pose_residual_m == 0.02);
}

TEST_CASE("LoopDetectionAssembler discards a detection with a lost page") {
  E2eSenderState sender;
  E2eReceiverState e2e;
  LoopDetectionAssembler assembler;
  const auto first = loop_frames(1, 100, sender);
  for (std::size_t i = 0; i < first.size(); ++i) {
    if (i == 3) continue;  // lost on the bus: the next frame's counter skips
    CHECK_FALSE(feed(assembler, e2e, first[i]));
  }
  // The next detection is complete again.
  const auto second = loop_frames(2, 200, sender);
  bool complete = false;
  for (const CanFrame& frame : second) complete = feed(assembler, e2e, frame);
  CHECK(complete);
  CHECK(assembler.detection().match_id == 2);
  CHECK(assembler.detection().query_frame == 200);
}
