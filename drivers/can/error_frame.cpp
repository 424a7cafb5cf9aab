#include "drivers/can/error_frame.hpp"

#include <linux/can/error.h>

namespace markloop::can {

ErrorFrameInfo decode_error_frame(const struct can_frame& frame) noexcept {
  ErrorFrameInfo info;
  if ((frame.can_id & CAN_ERR_FLAG) == 0 || frame.len != CAN_ERR_DLC) return info;
  info.valid = true;
  const std::uint32_t c = frame.can_id & CAN_ERR_MASK;
  info.classes = c;
  info.tx_timeout = (c & CAN_ERR_TX_TIMEOUT) != 0;
  info.lost_arbitration = (c & CAN_ERR_LOSTARB) != 0;
  info.controller = (c & CAN_ERR_CRTL) != 0;
  info.protocol = (c & CAN_ERR_PROT) != 0;
  info.transceiver = (c & CAN_ERR_TRX) != 0;
  info.no_ack = (c & CAN_ERR_ACK) != 0;
  info.bus_off = (c & CAN_ERR_BUSOFF) != 0;
  info.bus_error = (c & CAN_ERR_BUSERROR) != 0;
  info.restarted = (c & CAN_ERR_RESTARTED) != 0;
  if (info.controller) {
    const std::uint8_t s = frame.data[1];
    info.rx_overflow = (s & CAN_ERR_CRTL_RX_OVERFLOW) != 0;
    info.tx_overflow = (s & CAN_ERR_CRTL_TX_OVERFLOW) != 0;
    info.error_warning = (s & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) != 0;
    info.error_passive = (s & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) != 0;
    info.back_to_active = (s & CAN_ERR_CRTL_ACTIVE) != 0;
  }
#ifdef CAN_ERR_CNT
  if ((c & CAN_ERR_CNT) != 0) {
    info.has_error_counters = true;
    info.tx_error_count = frame.data[6];
    info.rx_error_count = frame.data[7];
  }
#endif
  return info;
}

}  // namespace markloop::can
