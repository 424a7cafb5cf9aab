// What can be checked about the SocketCAN driver without CAN in the kernel.
#include <catch2/catch_test_macros.hpp>

#include <sys/socket.h>

#include <cerrno>

#include "drivers/can/socketcan.hpp"

using namespace markloop::can;
using namespace std::chrono_literals;

TEST_CASE("wire layouts are the kernel's") {
  STATIC_CHECK(sizeof(struct can_frame) == CAN_MTU);
  STATIC_CHECK(sizeof(struct canfd_frame) == CANFD_MTU);
  STATIC_CHECK(sizeof(CanFrame{}.data) == CAN_MAX_DLEN);
}

TEST_CASE("a closed driver refuses work and close is idempotent") {
  SocketCan can;
  CHECK(can.state() == SocketCan::State::Closed);
  CHECK(can.fd() == -1);
  CanFrame f;
  f.id = 0x123;
  f.dlc = 1;
  CHECK(can.send(f) == std::errc::not_connected);
  CanFrame in;
  CHECK(can.receive(in) == std::errc::not_connected);
  CHECK(can.poll_readable(10ms) == std::errc::not_connected);
  CHECK(can.flush_tx() == std::errc::not_connected);
  f.dlc = 9;
  CHECK(can.send(f) == std::errc::invalid_argument);
  can.close();
  can.close();
  CHECK(can.state() == SocketCan::State::Closed);
}

TEST_CASE("open validates its arguments before touching the kernel") {
  SocketCan can;
  const CanFilter ok[] = {CanFilter::exact(0x123)};
  CHECK(can.open("", ok) == std::errc::invalid_argument);
  CHECK(can.open("a-very-long-interface-name", ok) == std::errc::invalid_argument);
  const CanFilter bad[] = {CanFilter::exact(0x800)};
  CHECK(can.open("vcan0", bad) == std::errc::invalid_argument);
  CHECK(can.state() == SocketCan::State::Closed);
}

TEST_CASE("open reports a missing kernel CAN stack or interface as an error") {
  SocketCan can;
  const CanFilter filters[] = {CanFilter::exact(0x123)};
  const std::error_code ec = can.open("markloop-none0", filters);
  // Without CAN in the kernel: EAFNOSUPPORT; with CAN: ENODEV.
  REQUIRE(ec);
  CHECK((ec.value() == EAFNOSUPPORT || ec.value() == ENODEV));
  CHECK(can.state() == SocketCan::State::Closed);
}
