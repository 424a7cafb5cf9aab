// Reads back what the ECU sent (its --can-out candump log): LoopDetection
// pages reassembled into detections, Status pages summarised, and every frame
// that fails its end-to-end checks counted by reason.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "app/common/result.hpp"
#include "dbc/markloop_messages.hpp"

namespace markloop::eval {

struct LoopReport {
  dbc::LoopDetection message;  // all six pages merged
  std::int64_t stamp_ns = 0;   // log timestamp of the page that completed it (the last one)
  std::size_t line = 0;        // log line of that page
};

// Frames of one CAN id rejected by decode(), by reason.
struct RejectCounts {
  std::uint64_t accepted = 0;
  std::uint64_t wrong_length = 0;
  std::uint64_t bad_crc = 0;
  std::uint64_t bad_counter = 0;  // alive counter repeated or skipped
  std::uint64_t out_of_range = 0;
  std::uint64_t unknown_page = 0;
  std::uint64_t rejected() const {
    return wrong_length + bad_crc + bad_counter + out_of_range + unknown_page;
  }
  void count(dbc::DecodeError error);
};

struct StatusSummary {
  dbc::Status last{};  // the latest value of every page's signals
  std::array<bool, dbc::Status::kPages.size()> page_seen{};
  double loop_time_max_ms = 0.0;                   // largest LoopTimeMax of any Status frame
  std::array<std::uint64_t, 4> frames_in_state{};  // by SystemState
  // Status frames with each fault flag set.
  std::uint64_t camera_lost = 0, camera_blind = 0, odometry_timeout = 0, bus_error = 0, overrun = 0;
};

struct EcuCanLog {
  std::vector<LoopReport> loops;
  // LoopDetection and Status frames of a length the DBC does not give them
  // (counted under wrong_length): the first one's line and length.
  std::size_t first_wrong_length_line = 0;
  std::size_t first_wrong_length_bytes = 0;
  std::size_t first_wrong_length_want = 0;
  RejectCounts loop_frames;
  RejectCounts status_frames;
  std::uint64_t detections_started = 0;  // accepted first pages
  std::uint64_t detections_incomplete = 0;
  std::uint64_t other_frames = 0;  // ids markloop does not send
  std::uint64_t frames = 0;
  StatusSummary status;
};

// The drive's clock, by its frames' times (frames.csv): the ECU stamps its
// log with it, so every stamp lies from kStampsBeforeDrive_s before the
// first frame to kStampsAfterDrive_s after the last one.
struct DriveTimes {
  double first_s = 0.0;
  double last_s = 0.0;
};
inline constexpr double kStampsBeforeDrive_s = 10.0;
inline constexpr double kStampsAfterDrive_s = 60.0;

// Reads the whole log (up to kMaxInputBytes). An error reads
// "FILE:LINE:COLUMN: what in 'line'" on a line that is not a candump -l
// frame, "FILE:LINE: what" on a stamp that goes back in time or (with
// `drive`) lies outside the drive, or on a last line cut short (no newline,
// and a LoopDetection or Status frame too short), or "FILE: what" when the
// file cannot be read. Frames that parse but fail the E2E checks are not
// errors: they are counted.
Result<EcuCanLog> read_ecu_can_log(const std::string& path, const DriveTimes* drive = nullptr);

// What a log that was read deserves a word about (one message each, naming
// the file): frames of the wrong length on the ECU's ids, no frame of the
// ECU at all.
std::vector<std::string> can_log_warnings(const std::string& path, const EcuCanLog& log);

}  // namespace markloop::eval
