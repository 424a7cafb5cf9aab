// The receiving end of $NOTIFY_SOCKET for tests: a bound datagram socket,
// as systemd holds it.
#pragma once

#include <catch2/catch_test_macros.hpp>

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <string>

namespace markloop::ecu::testing {

struct NotifyListener {
  int fd = -1;
  std::string path;
  explicit NotifyListener(const std::string& p) : path(p) {
    ::unlink(path.c_str());
    fd = ::socket(AF_UNIX, SOCK_DGRAM, 0);
    sockaddr_un address{};
    address.sun_family = AF_UNIX;
    std::strncpy(address.sun_path, path.c_str(), sizeof address.sun_path - 1);
    REQUIRE(::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0);
  }
  NotifyListener(const NotifyListener&) = delete;
  NotifyListener& operator=(const NotifyListener&) = delete;
  ~NotifyListener() {
    ::close(fd);
    ::unlink(path.c_str());
  }
  // The next message, or "(nothing)" when none arrives within `wait`.
  std::string receive(std::chrono::milliseconds wait = std::chrono::milliseconds(0)) const {
    pollfd ready{fd, POLLIN, 0};
    if (::poll(&ready, 1, static_cast<int>(wait.count())) <= 0) return "(nothing)";
    char buffer[256] = {};
    const ssize_t n = ::recv(fd, buffer, sizeof buffer - 1, MSG_DONTWAIT);
    return n < 0 ? std::string("(nothing)") : std::string(buffer, static_cast<std::size_t>(n));
  }
};

}  // namespace markloop::ecu::testing
