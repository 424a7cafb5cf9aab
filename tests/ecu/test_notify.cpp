// The sd_notify protocol without libsystemd: datagrams to $NOTIFY_SOCKET.
#include <catch2/catch_test_macros.hpp>

#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <string>

#include "platform/os.hpp"

namespace {

struct Listener {
  int fd = -1;
  std::string path;
  explicit Listener(const std::string& p) : path(p) {
    ::unlink(path.c_str());
    fd = ::socket(AF_UNIX, SOCK_DGRAM, 0);
    sockaddr_un address{};
    address.sun_family = AF_UNIX;
    std::strncpy(address.sun_path, path.c_str(), sizeof address.sun_path - 1);
    REQUIRE(::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0);
  }
  ~Listener() {
    ::close(fd);
    ::unlink(path.c_str());
  }
  std::string receive() const {
    char buffer[256] = {};
    const ssize_t n = ::recv(fd, buffer, sizeof buffer - 1, MSG_DONTWAIT);
    return n < 0 ? std::string("(nothing)") : std::string(buffer, static_cast<std::size_t>(n));
  }
};

}  // namespace

TEST_CASE("READY and WATCHDOG reach the socket named in NOTIFY_SOCKET; watchdog at half WatchdogSec") {
  Listener listener("/tmp/markloop-notify-test.sock");
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
