#include "app/tools/eval/can_log.hpp"

#include <cstdio>
#include <string_view>

#include "app/tools/common/tool_files.hpp"
#include "app/tools/eval/inputs.hpp"
#include "dbc/loop_detection_assembler.hpp"
#include "drivers/can/candump_log.hpp"

namespace markloop::eval {

void RejectCounts::count(dbc::DecodeError error) {
  switch (error) {
    case dbc::DecodeError::None:
      ++accepted;
      break;
    case dbc::DecodeError::WrongLength:
      ++wrong_length;
      break;
    case dbc::DecodeError::BadCrc:
      ++bad_crc;
      break;
    case dbc::DecodeError::BadCounter:
      ++bad_counter;
      break;
    case dbc::DecodeError::OutOfRange:
      ++out_of_range;
      break;
    case dbc::DecodeError::UnknownPage:
      ++unknown_page;
      break;
  }
}

namespace {

// Longer lines are no candump line; the message quotes no more of them.
constexpr std::size_t kMaxLine = 256;

// One line as a frame; false with "FILE:LINE:COLUMN: what in 'line'".
bool parse_line(const std::string& path, std::size_t number, std::string_view line,
                can::CandumpRecord& record, std::string& error) {
  can::CandumpLineError problem;
  if (line.size() > kMaxLine) {
    problem = {kMaxLine + 1, "line too long"};
    line = line.substr(0, kMaxLine);
  } else if (can::parse_candump_line(line, record, problem)) {
    return true;
  }
  error = path + ":" + std::to_string(number) + ":" + std::to_string(problem.column) + ": " + problem.what +
          " in '" + std::string(line) + "'";
  return false;
}

// "12.345678" (seconds, as candump writes them).
std::string stamp_text(std::int64_t ns) {
  char text[48];
  const std::int64_t us = ns / 1000;
  std::snprintf(text, sizeof text, "%s%lld.%06lld", us < 0 ? "-" : "",
                (long long)((us < 0 ? -us : us) / 1000000), (long long)((us < 0 ? -us : us) % 1000000));
  return text;
}

void note_wrong_length(EcuCanLog& out, std::size_t line, std::size_t bytes, std::size_t want) {
  if (out.first_wrong_length_line != 0) return;
  out.first_wrong_length_line = line;
  out.first_wrong_length_bytes = bytes;
  out.first_wrong_length_want = want;
}

std::string where(const std::string& path, std::size_t line) {
  return path + ":" + std::to_string(line) + ": ";
}

}  // namespace

bool read_ecu_can_log(const std::string& path, EcuCanLog& out, std::string& error, const DriveTimes* drive) {
  out = EcuCanLog{};
  std::string text;
  if (!tools::read_input(path, kMaxInputBytes, "a CAN log", text, error)) return false;
  Progress progress(path, count_lines(text));
  tools::Lines lines(text);
  // The log is the ECU's own output in send order, so the alive counters
  // must advance by exactly one per frame of an id.
  dbc::E2eReceiverState loop_e2e, status_e2e;
  dbc::LoopDetectionAssembler assembler;
  dbc::LoopDetection page{};
  dbc::Status status_page{};
  can::CandumpRecord record;
  std::string_view line;
  std::int64_t previous_ns = 0;
  bool last_frame_too_short = false;  // the last line's frame: an ECU id, short of its length
  std::size_t last_frame_bytes = 0, last_frame_want = 0;
  while (lines.next(line)) {
    if (!parse_line(path, lines.number(), line, record, error)) return false;
    ++out.frames;
    if ((out.frames & 0xFFF) == 0) progress.update(lines.number());
    const can::CanFrame& frame = record.frame;
    // The stamps are the drive's clock, in send order: a log on another
    // clock would give every latency as nonsense.
    if (out.frames > 1 && frame.timestamp_ns < previous_ns) {
      error = where(path, lines.number()) + "stamp " + stamp_text(frame.timestamp_ns) +
              " s is before the line above's " + stamp_text(previous_ns) +
              " s: the ECU logs its frames in send order, on the drive's clock";
      return false;
    }
    previous_ns = frame.timestamp_ns;
    if (drive != nullptr) {
      const double stamp_s = static_cast<double>(frame.timestamp_ns) * 1e-9;
      if (!(stamp_s >= drive->first_s - kStampsBeforeDrive_s &&
            stamp_s <= drive->last_s + kStampsAfterDrive_s)) {
        char span[160];
        std::snprintf(span, sizeof span, "(%.3f to %.3f s by frames.csv; %g s before and %g s after allowed)",
                      drive->first_s, drive->last_s, kStampsBeforeDrive_s, kStampsAfterDrive_s);
        error = where(path, lines.number()) + "stamp " + stamp_text(frame.timestamp_ns) +
                " s lies outside the drive " + span +
                ": the ECU stamps its log on the drive's clock; is this log on the wall clock, or of another "
                "drive?";
        return false;
      }
    }
    last_frame_too_short = false;
    if (frame.extended || (frame.id != dbc::LoopDetection::kId && frame.id != dbc::Status::kId)) {
      ++out.other_frames;
      continue;
    }
    if (frame.id == dbc::LoopDetection::kId) {
      const dbc::DecodeError result_code = dbc::decode(frame.payload(), loop_e2e, page);
      out.loop_frames.count(result_code);
      if (result_code == dbc::DecodeError::WrongLength) {
        note_wrong_length(out, lines.number(), frame.dlc, dbc::LoopDetection::kLength);
        last_frame_too_short = frame.dlc < dbc::LoopDetection::kLength;
        last_frame_bytes = frame.dlc;
        last_frame_want = dbc::LoopDetection::kLength;
      }
      if (result_code != dbc::DecodeError::None) {
        assembler.drop();
        continue;
      }
      if (page.loop_page == dbc::LoopDetection::kPages[0]) ++out.detections_started;
      if (assembler.add(page))
        out.loops.push_back({assembler.detection(), frame.timestamp_ns, lines.number()});
      continue;
    }
    const dbc::DecodeError result_code = dbc::decode(frame.payload(), status_e2e, status_page);
    out.status_frames.count(result_code);
    if (result_code == dbc::DecodeError::WrongLength) {
      note_wrong_length(out, lines.number(), frame.dlc, dbc::Status::kLength);
      last_frame_too_short = frame.dlc < dbc::Status::kLength;
      last_frame_bytes = frame.dlc;
      last_frame_want = dbc::Status::kLength;
    }
    if (result_code != dbc::DecodeError::None) continue;
    StatusSummary& s = out.status;
    s.last = status_page;
    s.page_seen[static_cast<std::size_t>(status_page.status_page)] = true;
    if (status_page.status_page == dbc::StatusPage::Timing &&
        status_page.loop_time_max_ms > s.loop_time_max_ms)
      s.loop_time_max_ms = status_page.loop_time_max_ms;
    ++s.frames_in_state[static_cast<std::size_t>(status_page.system_state)];
    s.camera_lost += status_page.fault_camera_lost ? 1 : 0;
    // Page 3's own flag: a frame of another page does not carry it.
    if (status_page.status_page == dbc::StatusPage::Perception)
      s.camera_blind += status_page.fault_camera_blind ? 1 : 0;
    s.odometry_timeout += status_page.fault_odometry_timeout ? 1 : 0;
    s.bus_error += status_page.fault_bus_error ? 1 : 0;
    s.overrun += status_page.fault_overrun ? 1 : 0;
  }
  // candump ends every line with a newline: a last line without one, whose
  // frame is short of its length, is a log cut mid-line (a full disk, a
  // copy stopped half-way), not a frame the ECU sent.
  if (last_frame_too_short && !text.empty() && text.back() != '\n') {
    error = where(path, lines.number()) +
            "the last line is cut short: no newline at its end, and its frame has " +
            std::to_string(last_frame_bytes) + " bytes where the ECU sends " +
            std::to_string(last_frame_want) + " (was the log cut?)";
    return false;
  }
  progress.finish();
  out.detections_incomplete = out.detections_started - out.loops.size();
  return true;
}

std::vector<std::string> can_log_warnings(const std::string& path, const EcuCanLog& log) {
  std::vector<std::string> warnings;
  const std::uint64_t ecu_frames = log.loop_frames.accepted + log.loop_frames.rejected() +
                                   log.status_frames.accepted + log.status_frames.rejected();
  if (ecu_frames == 0) {
    const std::string held = log.frames == 0 ? "it holds no frame"
                             : log.frames == 1
                                 ? "its one frame is of another id"
                                 : "its " + std::to_string(log.frames) + " frames are of other ids";
    warnings.push_back(path + ": no LoopDetection or Status frame: is this the ECU's log? (" + held + ")");
    return warnings;
  }
  const std::uint64_t wrong = log.loop_frames.wrong_length + log.status_frames.wrong_length;
  if (wrong > 0)
    warnings.push_back(where(path, log.first_wrong_length_line) + std::to_string(wrong) + " of " +
                       std::to_string(ecu_frames) +
                       " LoopDetection and Status frames have the wrong length (this one " +
                       std::to_string(log.first_wrong_length_bytes) + " bytes, the DBC's " +
                       std::to_string(log.first_wrong_length_want) + "): rejected, counted under 'length'");
  return warnings;
}

}  // namespace markloop::eval
