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

// "FILE:LINE: what" when a frame's stamp goes back in time or lies outside
// the drive. The stamps are the drive's clock, in send order: a log on
// another clock would give every latency as nonsense.
class StampCheck {
 public:
  StampCheck(const std::string& path, const DriveTimes* drive) : path_(path), drive_(drive) {}

  Status check(std::size_t line, std::int64_t stamp_ns) {
    const bool first = !seen_;
    seen_ = true;
    if (!first && stamp_ns < previous_ns_)
      return error(where(path_, line) + "stamp " + stamp_text(stamp_ns) + " s is before the line above's " +
                   stamp_text(previous_ns_) +
                   " s: the ECU logs its frames in send order, on the drive's clock");
    previous_ns_ = stamp_ns;
    if (drive_ == nullptr) return {};
    const double stamp_s = static_cast<double>(stamp_ns) * 1e-9;
    if (stamp_s >= drive_->first_s - kStampsBeforeDrive_s && stamp_s <= drive_->last_s + kStampsAfterDrive_s)
      return {};
    char span[160];
    std::snprintf(span, sizeof span, "(%.3f to %.3f s by frames.csv; %g s before and %g s after allowed)",
                  drive_->first_s, drive_->last_s, kStampsBeforeDrive_s, kStampsAfterDrive_s);
    return error(
        where(path_, line) + "stamp " + stamp_text(stamp_ns) + " s lies outside the drive " + span +
        ": the ECU stamps its log on the drive's clock; is this log on the wall clock, or of another "
        "drive?");
  }

 private:
  const std::string& path_;
  const DriveTimes* drive_;
  bool seen_ = false;
  std::int64_t previous_ns_ = 0;
};

// The ECU's frames decoded and counted as they come. The log is the ECU's
// own output in send order, so the alive counters must advance by exactly
// one per frame of an id.
class FrameDecoder {
 public:
  explicit FrameDecoder(EcuCanLog& out) : out_(out) {}

  void take(const can::CanFrame& frame, std::size_t line) {
    last_frame_too_short_ = false;
    if (frame.extended || (frame.id != dbc::LoopDetection::kId && frame.id != dbc::Status::kId))
      ++out_.other_frames;
    else if (frame.id == dbc::LoopDetection::kId)
      take_loop_page(frame, line);
    else
      take_status_page(frame, line);
  }

  // The last frame taken: one of the ECU's ids, short of its length.
  bool last_frame_too_short() const { return last_frame_too_short_; }
  std::size_t last_frame_bytes() const { return last_frame_bytes_; }
  std::size_t last_frame_want() const { return last_frame_want_; }

 private:
  void note_length(dbc::DecodeError result, const can::CanFrame& frame, std::size_t line, std::size_t want) {
    if (result != dbc::DecodeError::WrongLength) return;
    note_wrong_length(out_, line, frame.dlc, want);
    last_frame_too_short_ = frame.dlc < want;
    last_frame_bytes_ = frame.dlc;
    last_frame_want_ = want;
  }

  void take_loop_page(const can::CanFrame& frame, std::size_t line) {
    const dbc::DecodeError result = dbc::decode(frame.payload(), loop_e2e_, page_);
    out_.loop_frames.count(result);
    note_length(result, frame, line, dbc::LoopDetection::kLength);
    if (result != dbc::DecodeError::None) {
      assembler_.drop();
      return;
    }
    if (page_.loop_page == dbc::LoopDetection::kPages[0]) ++out_.detections_started;
    if (assembler_.add(page_)) out_.loops.push_back({assembler_.detection(), frame.timestamp_ns, line});
  }

  void take_status_page(const can::CanFrame& frame, std::size_t line) {
    const dbc::DecodeError result = dbc::decode(frame.payload(), status_e2e_, status_page_);
    out_.status_frames.count(result);
    note_length(result, frame, line, dbc::Status::kLength);
    if (result != dbc::DecodeError::None) return;
    StatusSummary& s = out_.status;
    const dbc::Status& p = status_page_;
    s.last = p;
    s.page_seen[static_cast<std::size_t>(p.status_page)] = true;
    if (p.status_page == dbc::StatusPage::Timing && p.loop_time_max_ms > s.loop_time_max_ms)
      s.loop_time_max_ms = p.loop_time_max_ms;
    ++s.frames_in_state[static_cast<std::size_t>(p.system_state)];
    s.camera_lost += p.fault_camera_lost ? 1 : 0;
    // Page 3's own flag: a frame of another page does not carry it.
    if (p.status_page == dbc::StatusPage::Perception) s.camera_blind += p.fault_camera_blind ? 1 : 0;
    s.odometry_timeout += p.fault_odometry_timeout ? 1 : 0;
    s.bus_error += p.fault_bus_error ? 1 : 0;
    s.overrun += p.fault_overrun ? 1 : 0;
  }

  EcuCanLog& out_;
  dbc::E2eReceiverState loop_e2e_, status_e2e_;
  dbc::LoopDetectionAssembler assembler_;
  dbc::LoopDetection page_{};
  dbc::Status status_page_{};
  bool last_frame_too_short_ = false;
  std::size_t last_frame_bytes_ = 0, last_frame_want_ = 0;
};

// candump ends every line with a newline: a last line without one, whose
// frame is short of its length, is a log cut mid-line (a full disk, a copy
// stopped half-way), not a frame the ECU sent.
Status check_last_line(const std::string& path, const std::string& text, std::size_t line,
                       const FrameDecoder& decoder) {
  if (!decoder.last_frame_too_short() || text.empty() || text.back() == '\n') return {};
  return error(where(path, line) + "the last line is cut short: no newline at its end, and its frame has " +
               std::to_string(decoder.last_frame_bytes()) + " bytes where the ECU sends " +
               std::to_string(decoder.last_frame_want()) + " (was the log cut?)");
}

}  // namespace

Result<EcuCanLog> read_ecu_can_log(const std::string& path, const DriveTimes* drive) {
  EcuCanLog out;
  const Result<std::string> read = tools::read_input(path, kMaxInputBytes, "a CAN log");
  if (!read) return read.error();
  const std::string& text = *read;
  std::string problem;
  Progress progress(path, count_lines(text));
  tools::Lines lines(text);
  StampCheck stamps(path, drive);
  FrameDecoder decoder(out);
  can::CandumpRecord record;
  std::string_view line;
  while (lines.next(line)) {
    if (!parse_line(path, lines.number(), line, record, problem)) return error(problem);
    ++out.frames;
    if ((out.frames & 0xFFF) == 0) progress.update(lines.number());
    if (Status stamp = stamps.check(lines.number(), record.frame.timestamp_ns); !stamp) return stamp.error();
    decoder.take(record.frame, lines.number());
  }
  if (Status last = check_last_line(path, text, lines.number(), decoder); !last) return last.error();
  progress.finish();
  out.detections_incomplete = out.detections_started - out.loops.size();
  return out;
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
