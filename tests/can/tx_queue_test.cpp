// The application-side transmit ring, driven by an injected send function
// (vcan has no real TX back-pressure, so ENOBUFS cannot be provoked there).
#include <catch2/catch_test_macros.hpp>

#include <vector>

#include "drivers/can/tx_queue.hpp"

using namespace markloop::can;

namespace {
CanFrame frame(std::uint32_t n) {
  CanFrame f;
  f.id = n;
  f.dlc = 1;
  f.data[0] = static_cast<std::uint8_t>(n);
  return f;
}
}  // namespace

TEST_CASE("the ring drops the oldest element when full") {
  DropOldestRing<int, 4> ring;
  for (int i = 0; i < 4; ++i) CHECK_FALSE(ring.push(i));
  CHECK(ring.full());
  CHECK(ring.push(4));
  CHECK(ring.push(5));
  REQUIRE(ring.size() == 4);
  CHECK(ring[0] == 2);
  CHECK(ring[3] == 5);
  ring.pop_front();
  CHECK(ring.front() == 3);
  ring.clear();
  CHECK(ring.empty());
}

TEST_CASE("a full kernel queue never loses the newest frame") {
  TxQueue<32> queue;
  std::vector<std::uint32_t> kernel;  // what the fake kernel accepted
  std::size_t kernel_room = 0;        // frames the fake kernel accepts before ENOBUFS
  auto send = [&](const CanFrame& f) {
    if (kernel_room == 0) return TxOutcome::RetryLater;  // ENOBUFS
    --kernel_room;
    kernel.push_back(f.id);
    return TxOutcome::Sent;
  };

  // The kernel is blocked while 100 frames are produced: the newest 32 stay.
  for (std::uint32_t i = 0; i < 100; ++i) {
    queue.push(frame(i));
    const FlushResult r = queue.flush(send);
    CHECK(r.sent == 0);
    CHECK(r.stopped_by == TxOutcome::RetryLater);
  }
  CHECK(queue.size() == 32);
  CHECK(queue.drops() == 68);
  CHECK(queue[0].id == 68);
  CHECK(queue[31].id == 99);

  // The kernel takes 10, then pushes back again: order is kept.
  kernel_room = 10;
  FlushResult r = queue.flush(send);
  CHECK(r.sent == 10);
  CHECK(r.stopped_by == TxOutcome::RetryLater);
  CHECK(queue.size() == 22);
  CHECK(kernel.front() == 68);
  CHECK(kernel.back() == 77);

  kernel_room = 1000;
  r = queue.flush(send);
  CHECK(r.sent == 22);
  CHECK(r.stopped_by == TxOutcome::Sent);
  CHECK(queue.empty());
  REQUIRE(kernel.size() == 32);
  for (std::size_t i = 0; i < kernel.size(); ++i) CHECK(kernel[i] == 68 + i);
}

TEST_CASE("discarded frames are skipped, an abort keeps the frame") {
  TxQueue<8> queue;
  for (std::uint32_t i = 0; i < 5; ++i) queue.push(frame(i));
  std::vector<std::uint32_t> sent;
  FlushResult r = queue.flush([&](const CanFrame& f) {
    if (f.id == 1) return TxOutcome::Discard;
    if (f.id == 3) return TxOutcome::Abort;
    sent.push_back(f.id);
    return TxOutcome::Sent;
  });
  CHECK(r.sent == 2);
  CHECK(r.discarded == 1);
  CHECK(r.stopped_by == TxOutcome::Abort);
  CHECK(queue.size() == 2);
  CHECK(queue[0].id == 3);
  CHECK(queue.clear() == 2);
  CHECK(queue.empty());
}
