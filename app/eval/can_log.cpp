#include "eval/can_log.hpp"

#include <string_view>

#include "cli/tool_files.hpp"
#include "drivers/can/candump_log.hpp"
#include "eval/inputs.hpp"
#include "markloop/dbc/loop_detection_assembler.hpp"

namespace markloop::eval {

void RejectCounts::count(dbc::DecodeError error) {
  switch (error) {
    case dbc::DecodeError::None: ++accepted; break;
    case dbc::DecodeError::WrongLength: ++wrong_length; break;
    case dbc::DecodeError::BadCrc: ++bad_crc; break;
    case dbc::DecodeError::BadCounter: ++bad_counter; break;
    case dbc::DecodeError::OutOfRange: ++out_of_range; break;
    case dbc::DecodeError::UnknownPage: ++unknown_page; break;
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

}  // namespace

bool read_ecu_can_log(const std::string& path, EcuCanLog& out, std::string& error) {
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
  while (lines.next(line)) {
    if (!parse_line(path, lines.number(), line, record, error)) return false;
    ++out.frames;
    if ((out.frames & 0xFFF) == 0) progress.update(lines.number());
    const can::CanFrame& frame = record.frame;
    if (frame.extended || (frame.id != dbc::LoopDetection::kId && frame.id != dbc::Status::kId)) {
      ++out.other_frames;
      continue;
    }
    if (frame.id == dbc::LoopDetection::kId) {
      const dbc::DecodeError result_code = dbc::decode(frame.payload(), loop_e2e, page);
      out.loop_frames.count(result_code);
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
    if (result_code != dbc::DecodeError::None) continue;
    StatusSummary& s = out.status;
    s.last = status_page;
    s.page_seen[static_cast<std::size_t>(status_page.status_page)] = true;
    if (status_page.status_page == dbc::StatusPage::Timing && status_page.loop_time_max_ms > s.loop_time_max_ms)
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
  progress.finish();
  out.detections_incomplete = out.detections_started - out.loops.size();
  return true;
}

}  // namespace markloop::eval
