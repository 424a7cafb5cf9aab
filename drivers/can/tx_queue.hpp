// The application-side transmit queue: a fixed-capacity ring that never
// allocates and, when full, drops the OLDEST frame so the newest is never
// lost. The kernel send is injected, so the policy is testable without CAN.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "drivers/can/can_frame.hpp"

namespace markloop::can {

template <typename T, std::size_t Capacity>
class DropOldestRing {
  static_assert(Capacity > 0);

 public:
  static constexpr std::size_t capacity() { return Capacity; }
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  bool full() const { return size_ == Capacity; }

  // Appends `value`; when full, first discards the oldest element and
  // returns true.
  bool push(const T& value) {
    bool dropped = false;
    if (size_ == Capacity) {
      pop_front();
      dropped = true;
    }
    items_[(head_ + size_) % Capacity] = value;
    ++size_;
    return dropped;
  }
  const T& front() const { return items_[head_]; }
  // Precondition: !empty().
  void pop_front() {
    head_ = (head_ + 1) % Capacity;
    --size_;
  }
  void clear() {
    head_ = 0;
    size_ = 0;
  }
  // i-th element from the oldest, i < size().
  const T& operator[](std::size_t i) const { return items_[(head_ + i) % Capacity]; }

 private:
  std::array<T, Capacity> items_{};
  std::size_t head_ = 0;
  std::size_t size_ = 0;
};

// What one attempt to hand a frame to the kernel gave.
enum class TxOutcome {
  Sent,        // frame accepted by the kernel: pop it, go on
  RetryLater,  // kernel queue full (ENOBUFS/EAGAIN): keep it, stop
  Discard,     // frame can never be sent (e.g. EINVAL): pop it, go on
  Abort,       // the interface is gone: keep it, stop
};

struct FlushResult {
  std::size_t sent = 0;
  std::size_t discarded = 0;
  TxOutcome stopped_by = TxOutcome::Sent;  // Sent: the queue is empty
};

template <std::size_t Capacity>
class TxQueue {
 public:
  static constexpr std::size_t capacity() { return Capacity; }

  // Queues `frame`; returns true when the oldest queued frame was dropped to
  // make room (counted in drops()).
  bool push(const CanFrame& frame) {
    const bool dropped = ring_.push(frame);
    if (dropped) ++drops_;
    return dropped;
  }

  // Hands queued frames, oldest first, to `send` (TxOutcome(const CanFrame&))
  // until the queue is empty or `send` says RetryLater/Abort.
  template <typename SendFn>
  FlushResult flush(SendFn&& send) {
    FlushResult result;
    while (!ring_.empty()) {
      const TxOutcome outcome = send(ring_.front());
      switch (outcome) {
        case TxOutcome::Sent:
          ring_.pop_front();
          ++result.sent;
          break;
        case TxOutcome::Discard:
          ring_.pop_front();
          ++result.discarded;
          break;
        case TxOutcome::RetryLater:
        case TxOutcome::Abort:
          result.stopped_by = outcome;
          return result;
      }
    }
    return result;
  }

  std::size_t size() const { return ring_.size(); }
  bool empty() const { return ring_.empty(); }
  // Drops everything queued; returns how many frames were dropped.
  std::size_t clear() {
    const std::size_t n = ring_.size();
    ring_.clear();
    return n;
  }
  const CanFrame& operator[](std::size_t i) const { return ring_[i]; }
  std::uint64_t drops() const { return drops_; }

 private:
  DropOldestRing<CanFrame, Capacity> ring_;
  std::uint64_t drops_ = 0;
};

}  // namespace markloop::can
