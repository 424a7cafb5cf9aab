#include "eval/can_log.hpp"

#include <cstring>

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

bool read_ecu_can_log(const std::string& path, EcuCanLog& out, std::string& error) {
  out = EcuCanLog{};
  can::CandumpLogReader reader;
  if (const std::error_code ec = reader.open(path)) {
    error = path + ": cannot open file: " + ec.message();
    return false;
  }
  Progress progress(path, count_lines(path));
  // The log is the ECU's own output in send order, so the alive counters
  // must advance by exactly one per frame of an id.
  dbc::E2eReceiverState loop_e2e, status_e2e;
  dbc::LoopDetectionAssembler assembler;
  dbc::LoopDetection page{};
  dbc::Status status_page{};
  can::CandumpRecord record;
  for (;;) {
    const auto result = reader.next(record);
    if (result == can::CandumpLogReader::Status::End) break;
    if (result == can::CandumpLogReader::Status::Error) {
      error = reader.error();
      return false;
    }
    ++out.frames;
    if ((out.frames & 0xFFF) == 0) progress.update(reader.line_number());
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
        out.loops.push_back({assembler.detection(), frame.timestamp_ns, reader.line_number()});
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
