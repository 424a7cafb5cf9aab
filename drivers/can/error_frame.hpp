// Decoding of SocketCAN error frames (CAN_ERR_FLAG set, see
// <linux/can/error.h>) into plain flags. Pure: no I/O, testable on any host.
#pragma once

#include <linux/can.h>

#include <cstdint>

namespace markloop::can {

struct ErrorFrameInfo {
  bool valid = false;         // CAN_ERR_FLAG set and len == CAN_ERR_DLC
  std::uint32_t classes = 0;  // the CAN_ERR_* class bits of can_id

  bool tx_timeout = false;
  bool lost_arbitration = false;
  bool controller = false;   // data[1] holds details
  bool protocol = false;     // data[2..3]
  bool transceiver = false;  // data[4]
  bool no_ack = false;
  bool bus_off = false;
  bool bus_error = false;
  bool restarted = false;

  // From the controller status byte (data[1]) when `controller`.
  bool rx_overflow = false;
  bool tx_overflow = false;
  bool error_warning = false;   // rx or tx warning level
  bool error_passive = false;   // rx or tx passive
  bool back_to_active = false;  // CAN_ERR_CRTL_ACTIVE

  // Error counters (data[6], data[7]) when CAN_ERR_CNT is set.
  bool has_error_counters = false;
  std::uint8_t tx_error_count = 0;
  std::uint8_t rx_error_count = 0;
};

// `frame` must have CAN_ERR_FLAG set; otherwise the result is !valid.
ErrorFrameInfo decode_error_frame(const struct can_frame& frame) noexcept;

}  // namespace markloop::can
