// A small synthetic run for markloop-eval's tests: truth files as the
// simulator writes them and ECU outputs made with the generated CAN encoders,
// with known figures (see the expectations below and in test_eval.cpp).
//
// Route: a 100 m x 100 m square driven twice anticlockwise at 1 m per frame,
// 10 frames per second (800 frames). Loop detections on the bus:
//   1. query 553 / match 150: the same place on the east side, 3 m apart
//      along the road: correct; true relative pose (3, 0, 0); sent with
//      (3.00, 0.40, 1.5 deg): error 0.4 m, 1.5 deg.
//   2. query 650 / match 100: 111.8 m apart: wrong.
//   3. a third detection whose page 2 has a broken CRC: incomplete (and the
//      page after it fails the alive-counter check).
// Status pages, one odometry frame (another id). Markings: 4 visible, 5
// detections, 3 matched (one only by IoU), 2 with the right label.
// Landmarks: 2, one on a marking of its class, one on none; no pass by a
// marking in range.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <string>

#include "dbc/markloop_messages.hpp"
#include "drivers/can/candump_log.hpp"

namespace markloop::eval::fixture {

inline constexpr std::size_t kFrames = 800;
inline constexpr double kFps = 10.0;

struct RoutePoint {
  double x, y, yaw;
};

// Position `s` metres along the square (anticlockwise from the origin).
inline RoutePoint route_at(double s) {
  s = std::fmod(s, 400.0);
  const double pi = std::numbers::pi;
  if (s < 100.0) return {s, 0.0, 0.0};
  if (s < 200.0) return {100.0, s - 100.0, pi / 2};
  if (s < 300.0) return {300.0 - s, 100.0, pi};
  return {0.0, 400.0 - s, -pi / 2};
}

class CandumpFile {
 public:
  explicit CandumpFile(const std::filesystem::path& path) : f_(std::fopen(path.c_str(), "w")) {}
  ~CandumpFile() { std::fclose(f_); }
  CandumpFile(const CandumpFile&) = delete;
  CandumpFile& operator=(const CandumpFile&) = delete;

  void write(const dbc::CanFrame& encoded, double t_s, bool break_crc = false) {
    can::CanFrame frame;
    frame.id = encoded.id;
    frame.dlc = encoded.length;
    frame.data = encoded.data;
    if (break_crc) frame.data[0] ^= 0x5A;
    frame.timestamp_ns = std::llround(t_s * 1e6) * 1000;
    char line[can::kCandumpMaxLine];
    const std::size_t n = can::format_candump_line(frame, "vcan0", line, sizeof line);
    std::fwrite(line, 1, n, f_);
  }

 private:
  std::FILE* f_;
};

// Sends the six pages of one detection starting at `t_s`, 1 us apart; the
// page with index `broken_page` (if < 6) gets a wrong CRC.
inline void send_detection(CandumpFile& log, dbc::E2eSenderState& sender, std::uint8_t id,
                           std::uint32_t query, std::uint32_t match, double dx, double dy, double dyaw_deg,
                           double t_s, std::size_t broken_page = 6) {
  dbc::LoopDetection m;
  m.match_id = id;
  m.query_frame = query;
  m.sequence_length = 4;
  m.match_frame = match;
  m.match_score = 0.8;
  m.query_time_s = query / kFps;
  m.match_time_s = match / kFps;
  m.pose_dx_m = dx;
  m.pose_dy_m = dy;
  m.pose_valid = true;
  m.pose_dyaw_deg = dyaw_deg;
  m.pose_residual_m = 0.05;
  for (std::size_t page = 0; page < dbc::LoopDetection::kPages.size(); ++page) {
    m.loop_page = dbc::LoopDetection::kPages[page];
    log.write(dbc::encode_frame(m, sender), t_s + 1e-6 * static_cast<double>(page), page == broken_page);
  }
}

inline void send_status(CandumpFile& log, dbc::E2eSenderState& sender, double t_s, std::uint32_t processed,
                        double loop_time_ms, bool overrun) {
  dbc::Status s;
  s.system_state = dbc::SystemState::Running;
  s.fault_overrun = overrun;
  s.frames_processed = processed;
  s.database_fill_percent = 1.5;
  s.frames_dropped = 2;
  s.loop_time_max_ms = loop_time_ms;
  s.landmark_count = 40;
  s.sequence_count = 150;
  for (std::size_t page = 0; page < dbc::Status::kPages.size(); ++page) {
    s.status_page = dbc::Status::kPages[page];
    log.write(dbc::encode_frame(s, sender), t_s + 1e-6 * static_cast<double>(page));
  }
}

inline void write_text(const std::filesystem::path& path, const std::string& text) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  std::fputs(text.c_str(), f);
  std::fclose(f);
}

// A rectangle as a quad "x1,y1,...,x4,y4".
inline std::string rectangle(double x0, double y0, double x1, double y1) {
  char text[128];
  std::snprintf(text, sizeof text, "%g,%g,%g,%g,%g,%g,%g,%g", x0, y0, x1, y0, x1, y1, x0, y1);
  return text;
}

inline void write_run(const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir);
  std::string frames = "frame,t,x,y,yaw\n";
  char line[128];
  for (std::size_t f = 0; f < kFrames; ++f) {
    const RoutePoint p = route_at(static_cast<double>(f));
    std::snprintf(line, sizeof line, "%zu,%.3f,%.4f,%.4f,%.6f\n", f, static_cast<double>(f) / kFps, p.x, p.y,
                  p.yaw);
    frames += line;
  }
  write_text(dir / "frames.csv", frames);
  write_text(dir / "markings.csv",
             "id,class,x,y,heading\n0,stop,50,3,0\n1,forward,100,40,1.5708\n2,crosswalk,40,100,3.1416\n"
             "3,bike,0,60,-1.5708\n");
  write_text(dir / "visible.csv",
             "frame,id,class,x1,y1,x2,y2,x3,y3,x4,y4\n"
             "10,0,stop," +
                 rectangle(100, 300, 200, 340) + "\n" + "10,1,forward," + rectangle(600, 300, 640, 400) +
                 "\n" + "11,2,crosswalk," + rectangle(0, 0, 100, 100) + "\n" + "11,3,bike," +
                 rectangle(900, 200, 950, 260) + "\n");
  write_text(dir / "ecu-detections.csv",
             "frame,label,score,x1,y1,x2,y2,x3,y3,x4,y4,ground_x,ground_y\n"
             "10,stop,0.9," +
                 rectangle(110, 305, 210, 345) + ",8.0,0.5\n" + "10,leftturn,0.7," +
                 rectangle(598, 310, 642, 390) + ",9.0,-1.5\n" + "10,ped,0.6," +
                 rectangle(300, 100, 340, 140) + ",20.0,3.0\n" + "11,crosswalk,0.8," +
                 rectangle(52, 0, 152, 100) + ",7.0,0.0\n" + "12,ped,0.5," + rectangle(300, 100, 340, 140) +
                 ",20.0,3.0\n");
  // The ECU's odometry frame is the truth's here: the stop line's landmark
  // lies 0.2 m from it; the ped one on no marking.
  write_text(dir / "ecu-landmarks.csv",
             "label,observations,first_frame,last_frame,x,y,car_x,car_y,car_yaw,has_car_pose\n"
             "stop,4,30,48,50.2,3.0,48.0,0.0,0.0,1\n"
             "ped,3,15,19,20.0,20.0,19.0,0.0,0.0,1\n");

  CandumpFile log(dir / "ecu-can.log");
  dbc::E2eSenderState loop_sender, status_sender;
  send_status(log, status_sender, 0.1, 1, 12.5, true);
  dbc::E2eSenderState odometry_sender;
  dbc::VehicleOdometry odometry;
  log.write(dbc::encode_frame(odometry, odometry_sender), 0.2);
  // Detection 1: released by frame 570 (57.0 s), 4 ms of processing.
  send_detection(log, loop_sender, 0, 553, 150, 3.0, 0.4, 1.5, 57.004);
  send_status(log, status_sender, 57.1, 571, 7.0, false);
  // Detection 2: released by frame 665, 6 ms of processing.
  send_detection(log, loop_sender, 1, 650, 100, 1.0, 0.0, 0.0, 66.506);
  // Detection 3: page 2 corrupted.
  send_detection(log, loop_sender, 2, 700, 300, 0.5, 0.0, 0.0, 71.003, 2);
  send_status(log, status_sender, 79.9, 800, 6.0, false);
}

// The latencies of detections 1 and 2 (CAN stamp of the last page - QueryTime).
inline constexpr double kLatency1_s = 57.004005 - 55.3;
inline constexpr double kLatency2_s = 66.506005 - 65.0;

}  // namespace markloop::eval::fixture
