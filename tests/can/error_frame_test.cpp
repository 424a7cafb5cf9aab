#include <catch2/catch_test_macros.hpp>

#include <linux/can/error.h>

#include "drivers/can/error_frame.hpp"
#include "drivers/can/socketcan.hpp"

using namespace markloop::can;

namespace {
struct can_frame error_frame(std::uint32_t classes, std::uint8_t d1 = 0) {
  struct can_frame f {};
  f.can_id = CAN_ERR_FLAG | classes;
  f.len = CAN_ERR_DLC;
  f.data[1] = d1;
  return f;
}
}  // namespace

TEST_CASE("error frames decode into flags") {
  auto i = decode_error_frame(error_frame(CAN_ERR_BUSOFF));
  CHECK(i.valid);
  CHECK(i.bus_off);
  CHECK_FALSE(i.restarted);

  i = decode_error_frame(error_frame(CAN_ERR_RESTARTED));
  CHECK(i.restarted);
  CHECK_FALSE(i.bus_off);

  i = decode_error_frame(error_frame(CAN_ERR_TX_TIMEOUT | CAN_ERR_ACK | CAN_ERR_LOSTARB));
  CHECK(i.tx_timeout);
  CHECK(i.no_ack);
  CHECK(i.lost_arbitration);

  i = decode_error_frame(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_RX_OVERFLOW | CAN_ERR_CRTL_TX_PASSIVE));
  CHECK(i.controller);
  CHECK(i.rx_overflow);
  CHECK(i.error_passive);
  CHECK_FALSE(i.error_warning);
  CHECK_FALSE(i.back_to_active);

  i = decode_error_frame(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_RX_WARNING));
  CHECK(i.error_warning);
  i = decode_error_frame(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_ACTIVE));
  CHECK(i.back_to_active);

  auto cnt = error_frame(CAN_ERR_CNT | CAN_ERR_PROT | CAN_ERR_TRX | CAN_ERR_BUSERROR);
  cnt.data[6] = 96;
  cnt.data[7] = 128;
  i = decode_error_frame(cnt);
  CHECK(i.protocol);
  CHECK(i.transceiver);
  CHECK(i.bus_error);
  CHECK(i.has_error_counters);
  CHECK(i.tx_error_count == 96);
  CHECK(i.rx_error_count == 128);
}

TEST_CASE("malformed error frames are not trusted") {
  auto f = error_frame(CAN_ERR_BUSOFF);
  f.len = 4;  // error frames always carry 8 bytes
  CHECK_FALSE(decode_error_frame(f).valid);
  struct can_frame data {};
  data.can_id = 0x123;
  data.len = 8;
  CHECK_FALSE(decode_error_frame(data).valid);
}

TEST_CASE("error frames drive counters; bus-off outside Open is only counted") {
  SocketCan can;  // Closed: no socket needed for the decoder path
  can.handle_error_frame(error_frame(CAN_ERR_BUSOFF));
  can.handle_error_frame(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_TX_WARNING));
  auto bad = error_frame(CAN_ERR_ACK);
  bad.len = 2;
  can.handle_error_frame(bad);
  const auto& c = can.counters();
  CHECK(c.error_frames == 3);
  CHECK(c.error_frames_bad == 1);
  CHECK(c.error_classes.bus_off == 1);
  CHECK(c.error_classes.controller == 1);
  CHECK(c.error_classes.error_warning == 1);
  CHECK(c.bus_off == 0);  // not Open: no state change
  CHECK(can.state() == SocketCan::State::Closed);
}
