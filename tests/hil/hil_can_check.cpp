// Reads a candump log (what the bus carried) and checks what markloop sent:
// LoopDetection pages reassembled into detections with E2E (CRC, alive
// counter) checked, and Status pages. Prints the counts and the last Status.
//
//   markloop-hil-can-check LOG [--min-detections N] [--min-status N]
// Exit status 0 when both minimums are met, 1 otherwise, 2 on bad input.
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "dbc/loop_detection_assembler.hpp"
#include "dbc/markloop_messages.hpp"
#include "drivers/can/candump_log.hpp"

using namespace markloop;

int main(int argc, char** argv) {
  if (argc < 2 || std::string_view(argv[1]) == "--help") {
    std::puts("usage: markloop-hil-can-check LOG [--min-detections N] [--min-status N]");
    return argc < 2 ? 2 : 0;
  }
  unsigned long min_detections = 1, min_status = 1;
  for (int i = 2; i + 1 < argc; i += 2) {
    const std::string_view arg = argv[i];
    if (arg == "--min-detections")
      min_detections = std::strtoul(argv[i + 1], nullptr, 10);
    else if (arg == "--min-status")
      min_status = std::strtoul(argv[i + 1], nullptr, 10);
    else {
      std::fprintf(stderr, "markloop-hil-can-check: unknown option %s\n", argv[i]);
      return 2;
    }
  }
  can::CandumpLogReader reader;
  if (auto ec = reader.open(argv[1])) {
    std::fprintf(stderr, "markloop-hil-can-check: %s: %s\n", argv[1], ec.message().c_str());
    return 2;
  }
  dbc::E2eReceiverState loop_e2e, status_e2e;
  dbc::LoopDetection page;
  dbc::LoopDetectionAssembler assembler;
  dbc::Status status;
  unsigned long detections = 0, loop_rejected = 0, status_pages = 0, status_rejected = 0, odometry = 0,
                other = 0;
  can::CandumpRecord record;
  for (;;) {
    const auto result = reader.next(record);
    if (result == can::CandumpLogReader::Status::End) break;
    if (result == can::CandumpLogReader::Status::Error) {
      std::fprintf(stderr, "markloop-hil-can-check: %s\n", reader.error().c_str());
      return 2;
    }
    const can::CanFrame& f = record.frame;
    if (f.id == dbc::LoopDetection::kId) {
      if (dbc::decode(f.payload(), loop_e2e, page) != dbc::DecodeError::None) {
        ++loop_rejected;
        assembler.drop();
      } else if (assembler.add(page)) {
        ++detections;
        const dbc::LoopDetection& d = assembler.detection();
        std::printf(
            "detection %u: query frame %u, match frame %u, score %.2f, pose (%.2f m, %.2f m, %.2f deg)%s, "
            "residual %.3f m\n",
            d.match_id, d.query_frame, d.match_frame, d.match_score, d.pose_dx_m, d.pose_dy_m,
            d.pose_dyaw_deg, d.pose_valid ? "" : " (invalid)", d.pose_residual_m);
      }
    } else if (f.id == dbc::Status::kId) {
      if (dbc::decode(f.payload(), status_e2e, status) != dbc::DecodeError::None)
        ++status_rejected;
      else
        ++status_pages;
    } else if (f.id == dbc::VehicleOdometry::kId) {
      ++odometry;
    } else {
      ++other;
    }
  }
  std::printf(
      "bus: %lu odometry frames, %lu complete loop detections (%lu pages rejected), "
      "%lu Status pages (%lu rejected), %lu other frames\n",
      odometry, detections, loop_rejected, status_pages, status_rejected, other);
  std::printf(
      "last Status: state %u, faults camera %d odometry %d bus %d overrun %d, frames %u processed %u "
      "dropped, "
      "loop time max %.2f ms, %u landmarks, %u sequences\n",
      static_cast<unsigned>(status.system_state), status.fault_camera_lost, status.fault_odometry_timeout,
      status.fault_bus_error, status.fault_overrun, status.frames_processed, status.frames_dropped,
      status.loop_time_max_ms, status.landmark_count, status.sequence_count);
  // Rejected pages are reported, not failed: under an emulated CPU candump
  // itself loses frames, and a lost frame makes the next one's alive counter
  // jump. A detection with a lost or bad page is not complete, so not counted.
  const bool ok = detections >= min_detections && status_pages >= min_status;
  std::printf("%s\n", ok ? "PASS" : "FAIL");
  return ok ? 0 : 1;
}
