// Receive-side supervision: timeout of cyclic messages, and a per-message
// receiver that combines E2E counter state, timeout and decoding.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <span>

#include "dbc/e2e.hpp"

namespace markloop::dbc {

// Monotonic time since an arbitrary epoch (steady clock, CAN timestamps, or
// simulated time). Nanoseconds so that ms/us durations convert implicitly.
using Timestamp = std::chrono::nanoseconds;

// Raises the flag when no valid frame arrived for longer than `timeout`.
// Until start() or the first on_received() it reports timed out: no data yet
// is no data.
class ReceiveTimeout {
 public:
  constexpr explicit ReceiveTimeout(std::chrono::nanoseconds timeout) noexcept : timeout_(timeout) {}

  // Begin supervising at `now` with a full timeout of grace (e.g. at start).
  constexpr void start(Timestamp now) noexcept { on_received(now); }
  constexpr void on_received(Timestamp now) noexcept {
    last_ = now;
    seen_ = true;
  }
  constexpr void reset() noexcept { seen_ = false; }
  // Timed out once strictly more than `timeout` has passed since the last frame.
  constexpr bool timed_out(Timestamp now) const noexcept { return !seen_ || now - last_ > timeout_; }
  constexpr std::chrono::nanoseconds timeout() const noexcept { return timeout_; }

 private:
  std::chrono::nanoseconds timeout_;
  Timestamp last_{};
  bool seen_ = false;
};

// A classic CAN frame as the generated encoders produce it.
struct CanFrame {
  std::uint32_t id = 0;  // 11-bit standard id
  std::uint8_t length = 0;
  std::array<std::uint8_t, 8> data{};
};

// Encodes one frame of `message` with the sender's next alive counter. For a
// multiplexed message the page set in the message is encoded.
template <typename Message>
CanFrame encode_frame(const Message& message, E2eSenderState& sender) noexcept {
  CanFrame frame;
  frame.id = Message::kId;
  frame.length = encode(message, sender.next(), std::span<std::uint8_t, 8>{frame.data});
  return frame;
}

// Everything needed to receive one message id: E2E counter state, timeout
// supervision for cyclic messages, and error counts. Feed it every frame that
// arrives on Message::kId; `out` is written only when None is returned (for
// multiplexed messages only the received page's signals, so pages accumulate).
template <typename Message>
class Receiver {
 public:
  DecodeError receive(std::span<const std::uint8_t> payload, Timestamp now, Message& out) noexcept {
    // After a timeout the sender may have restarted: take its next counter as
    // is. Event messages have no timeout: their counter state is kept forever.
    if constexpr (Message::kIsCyclic) {
      if (timeout_.timed_out(now)) e2e_.reset();
    }
    const DecodeError error = decode(payload, e2e_, out);
    if (error == DecodeError::None) {
      timeout_.on_received(now);
      ++accepted_;
    } else {
      ++rejected_;
    }
    return error;
  }

  // Event messages (no cycle time) never time out.
  bool timed_out(Timestamp now) const noexcept {
    if constexpr (Message::kIsCyclic) {
      return timeout_.timed_out(now);
    } else {
      static_cast<void>(now);
      return false;
    }
  }
  void start(Timestamp now) noexcept { timeout_.start(now); }
  void reset() noexcept {
    e2e_.reset();
    timeout_.reset();
  }
  std::uint32_t accepted() const noexcept { return accepted_; }
  std::uint32_t rejected() const noexcept { return rejected_; }

 private:
  E2eReceiverState e2e_;
  ReceiveTimeout timeout_{std::chrono::nanoseconds{Message::kTimeout}};
  std::uint32_t accepted_ = 0;
  std::uint32_t rejected_ = 0;
};

}  // namespace markloop::dbc
