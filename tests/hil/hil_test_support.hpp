// Helpers for the hardware-in-the-loop tests: child processes (can-utils),
// a candump capture with marker-frame synchronisation, dbc <-> driver frames.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "dbc/receive.hpp"
#include "drivers/can/candump_log.hpp"
#include "drivers/can/socketcan.hpp"

extern char** environ;

namespace markloop::hil {

using namespace std::chrono_literals;
using can::CanFrame;

inline std::string can_if() {
  const char* v = std::getenv("HIL_CAN_IF");
  return v != nullptr && *v != '\0' ? v : "vcan0";
}

inline std::string results_dir() {
  const char* v = std::getenv("HIL_RESULTS");
  return v != nullptr && *v != '\0' ? v : "/tmp";
}

// Runs a shell command; returns its exit status (-1 when it did not exit).
inline int run(const std::string& command) {
  const int rc = std::system(command.c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

// A child process whose stdout and stderr go to a file.
class Process {
 public:
  Process(const std::vector<std::string>& argv, const std::string& output) {
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, output.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    // Its own process group, so stop() also ends what it started (a shell
    // loop's running cangen would otherwise outlive it and flood later tests).
    posix_spawnattr_t attributes;
    posix_spawnattr_init(&attributes);
    posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETPGROUP);
    posix_spawnattr_setpgroup(&attributes, 0);
    if (posix_spawnp(&pid_, args[0], &actions, &attributes, args.data(), environ) != 0) pid_ = -1;
    posix_spawnattr_destroy(&attributes);
    posix_spawn_file_actions_destroy(&actions);
  }
  ~Process() { stop(); }
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  bool started() const { return pid_ > 0; }
  // Signals the whole process group (SIGTERM), then waits for the leader;
  // returns its raw wait status (or -1).
  int stop(int sig = SIGTERM) {
    if (pid_ <= 0) return -1;
    ::kill(-pid_, sig);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
    return status;
  }

 private:
  pid_t pid_ = -1;
};

inline std::vector<std::string> read_lines(const std::string& path) {
  std::vector<std::string> lines;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

inline CanFrame make_frame(std::uint32_t id, bool extended, std::initializer_list<std::uint8_t> bytes) {
  CanFrame f;
  f.id = id;
  f.extended = extended;
  f.dlc = static_cast<std::uint8_t>(bytes.size());
  std::size_t i = 0;
  for (auto b : bytes) f.data[i++] = b;
  return f;
}

// The generated encoders produce dbc::CanFrame (standard ids only).
template <typename DbcFrame>
CanFrame from_dbc(const DbcFrame& d) {
  CanFrame f;
  f.id = d.id;
  f.dlc = d.length;
  f.data = d.data;
  return f;
}

inline std::string hex(const CanFrame& f) {
  static const char digits[] = "0123456789ABCDEF";
  std::string s;
  for (std::uint8_t i = 0; i < f.dlc; ++i) {
    s += digits[f.data[i] >> 4];
    s += digits[f.data[i] & 0xF];
  }
  return s;
}

// cansend syntax for a frame.
inline std::string cansend_arg(const CanFrame& f) {
  char id[16];
  std::snprintf(id, sizeof(id), f.extended ? "%08X" : "%03X", static_cast<unsigned>(f.id));
  return std::string(id) + "#" + hex(f);
}

// `candump -L` (log format on stdout, line-buffered through stdbuf) into a
// file in HIL_RESULTS, with optional candump filters ("123:7FF,...").
class CandumpCapture {
 public:
  CandumpCapture(const std::string& name, const std::string& filters)
      : path_(results_dir() + "/" + name + ".candump.log"),
        proc_({"stdbuf", "-oL", "candump", "-L", filters.empty() ? can_if() : can_if() + "," + filters},
              path_) {}

  bool started() const { return proc_.started(); }
  const std::string& path() const { return path_; }

  // Sends `marker` through `sender` every 20 ms until candump has logged it.
  bool sync(can::SocketCan& sender, const CanFrame& marker, std::chrono::milliseconds timeout = 10s) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      (void)sender.send(marker);
      std::this_thread::sleep_for(20ms);
      for (const auto& line : read_lines(path_)) {
        can::CandumpRecord r;
        can::CandumpLineError e;
        if (can::parse_candump_line(line, r, e) && can::same_content(r.frame, marker)) return true;
      }
    }
    return false;
  }

  // Stops candump; returns every line it wrote.
  std::vector<std::string> stop() {
    proc_.stop();
    return read_lines(path_);
  }

 private:
  std::string path_;
  Process proc_;
};

}  // namespace markloop::hil
