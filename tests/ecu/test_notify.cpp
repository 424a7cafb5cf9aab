// The sd_notify protocol without libsystemd: datagrams to $NOTIFY_SOCKET.
#include <catch2/catch_test_macros.hpp>

#include <cstdlib>

#include "platform/os.hpp"
#include "tests/ecu/notify_listener.hpp"

using markloop::ecu::testing::NotifyListener;

TEST_CASE("READY and WATCHDOG reach the socket named in NOTIFY_SOCKET; watchdog at half WatchdogSec") {
  NotifyListener listener("/tmp/markloop-notify-test.sock");
  ::setenv("NOTIFY_SOCKET", listener.path.c_str(), 1);
  ::setenv("WATCHDOG_USEC", "5000000", 1);
  markloop::platform::SystemdNotifier notifier;
  REQUIRE_FALSE(notifier.open());
  CHECK(notifier.enabled());
  CHECK(notifier.watchdog_interval() == std::chrono::milliseconds(2500));
  REQUIRE_FALSE(notifier.notify("READY=1"));
  CHECK(listener.receive() == "READY=1");
  REQUIRE_FALSE(notifier.notify("WATCHDOG=1"));
  CHECK(listener.receive() == "WATCHDOG=1");
  ::unsetenv("NOTIFY_SOCKET");
  ::unsetenv("WATCHDOG_USEC");
}

TEST_CASE("without NOTIFY_SOCKET notifications are no-ops") {
  ::unsetenv("NOTIFY_SOCKET");
  markloop::platform::SystemdNotifier notifier;
  REQUIRE_FALSE(notifier.open());
  CHECK_FALSE(notifier.enabled());
  CHECK_FALSE(notifier.notify("READY=1"));
  CHECK(notifier.watchdog_interval().count() == 0);
}
