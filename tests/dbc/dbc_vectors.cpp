// Prints frames encoded by the generated C++ code, one per line:
//   <id hex> <payload hex> <Signal>=<physical value> ...
// check_with_canmatrix.py decodes and re-encodes them with canmatrix, an
// independent DBC implementation, and compares. Values are on the DBC grid so
// that both sides must agree exactly.
#include <cstdint>
#include <cstdio>
#include <initializer_list>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

#include "dbc/markloop_messages.hpp"

using namespace markloop::dbc;

namespace {

using Field = std::pair<std::string_view, double>;

template <typename Message>
void print(const Message& message, std::uint8_t counter, std::span<const Field> fields) {
  std::array<std::uint8_t, 8> bytes{};
  const std::uint8_t length = encode(message, counter, std::span<std::uint8_t, 8>{bytes});
  std::printf("0x%03X ", static_cast<unsigned>(Message::kId));
  for (std::size_t i = 0; i < length; ++i) std::printf("%02X", static_cast<unsigned>(bytes[i]));
  for (const auto& [name, value] : fields) {
    std::printf(" %.*s=%.6f", static_cast<int>(name.size()), name.data(), value);
  }
  std::printf("\n");
}

template <typename Message>
void print(const Message& message, std::uint8_t counter, std::initializer_list<Field> fields) {
  print(message, counter, std::span<const Field>(fields.begin(), fields.size()));
}

double raw(auto value) {
  return static_cast<double>(value);
}

void print_odometry() {
  VehicleOdometry odo;
  odo.wheel_speed_m_per_s = -12.34;
  odo.yaw_rate_deg_per_s = 250.5;
  odo.wheel_speed_valid = true;
  print(odo, 9,
        {{"OdoAliveCounter", 9},
         {"WheelSpeed", -12.34},
         {"YawRate", 250.5},
         {"WheelSpeedValid", 1},
         {"YawRateValid", 0}});
  odo.wheel_speed_m_per_s = 100.0;
  odo.yaw_rate_deg_per_s = -300.0;
  odo.wheel_speed_valid = false;
  odo.yaw_rate_valid = true;
  print(odo, 15,
        {{"OdoAliveCounter", 15},
         {"WheelSpeed", 100.0},
         {"YawRate", -300.0},
         {"WheelSpeedValid", 0},
         {"YawRateValid", 1}});
}

void print_commands() {
  Command command;
  command.command_code = CommandCode::ResetDatabase;
  print(command, 0, {{"CmdAliveCounter", 0}, {"CommandCode", raw(CommandCode::ResetDatabase)}});
  command.command_code = CommandCode::SaveMap;
  print(command, 1, {{"CmdAliveCounter", 1}, {"CommandCode", raw(CommandCode::SaveMap)}});
}

void print_loop_pages() {
  LoopDetection loop;
  loop.match_id = 77;
  loop.query_frame = 3000000001U;
  loop.sequence_length = 6;
  loop.match_frame = 1234567;
  loop.match_score = 0.876;
  loop.query_time_s = 100000.001;
  loop.match_time_s = 41.152;
  loop.pose_dx_m = -2.71;
  loop.pose_dy_m = 0.35;
  loop.pose_valid = true;
  loop.pose_dyaw_deg = -12.34;
  loop.pose_residual_m = 0.042;
  std::uint8_t counter = 13;
  for (const LoopPage page : LoopDetection::kPages) {
    loop.loop_page = page;
    const double p = raw(page);
    const std::uint8_t c = counter++ % 16;
    switch (page) {
      case LoopPage::Query:
        print(loop, c,
              {{"LoopAliveCounter", c},
               {"LoopPage", p},
               {"MatchId", 77},
               {"QueryFrame", 3000000001.0},
               {"SequenceLength", 6}});
        break;
      case LoopPage::Match:
        print(loop, c,
              {{"LoopAliveCounter", c},
               {"LoopPage", p},
               {"MatchId", 77},
               {"MatchFrame", 1234567},
               {"MatchScore", 0.876}});
        break;
      case LoopPage::QueryTime:
        print(loop, c,
              {{"LoopAliveCounter", c}, {"LoopPage", p}, {"MatchId", 77}, {"QueryTime", 100000.001}});
        break;
      case LoopPage::MatchTime:
        print(loop, c, {{"LoopAliveCounter", c}, {"LoopPage", p}, {"MatchId", 77}, {"MatchTime", 41.152}});
        break;
      case LoopPage::Translation:
        print(loop, c,
              {{"LoopAliveCounter", c},
               {"LoopPage", p},
               {"MatchId", 77},
               {"PoseDx", -2.71},
               {"PoseDy", 0.35},
               {"PoseValid", 1}});
        break;
      case LoopPage::RotationResidual:
        print(loop, c,
              {{"LoopAliveCounter", c},
               {"LoopPage", p},
               {"MatchId", 77},
               {"PoseDyaw", -12.34},
               {"PoseResidual", 0.042}});
        break;
    }
  }
}

void print_status_pages() {
  Status status;
  status.system_state = SystemState::Running;
  status.fault_camera_lost = true;
  status.fault_overrun = true;
  status.frames_processed = 987654321;
  status.database_fill_percent = 37.5;
  status.frames_dropped = 4321;
  status.loop_time_max_ms = 8.76;
  status.landmark_count = 262144;
  status.sequence_count = 1000001;
  status.fault_camera_blind = true;
  status.frames_blind = 3000000000U;
  status.odometry_scale = 1.01234;
  status.odometry_scale_error = 0.00042;
  status.odometry_scale_valid = true;
  // Every page carries the state and the fault bits, then its own signals.
  std::uint8_t counter = 0;
  const auto print_page = [&](std::initializer_list<Field> own) {
    const std::uint8_t c = counter++;
    std::vector<Field> fields = {{"StatusAliveCounter", c},
                                 {"StatusPage", raw(status.status_page)},
                                 {"SystemState", raw(SystemState::Running)},
                                 {"FaultCameraLost", 1},
                                 {"FaultOdometryTimeout", 0},
                                 {"FaultBusError", 0},
                                 {"FaultOverrun", 1}};
    fields.insert(fields.end(), own);
    print(status, c, std::span<const Field>(fields));
  };
  for (const StatusPage page : Status::kPages) {
    status.status_page = page;
    switch (page) {
      case StatusPage::Processing:
        print_page({{"FramesProcessed", 987654321}, {"DatabaseFill", 37.5}});
        break;
      case StatusPage::Timing:
        print_page({{"FramesDropped", 4321}, {"LoopTimeMax", 8.76}});
        break;
      case StatusPage::Database:
        print_page({{"LandmarkCount", 262144}, {"SequenceCount", 1000001}});
        break;
      case StatusPage::Perception:
        print_page({{"FaultCameraBlind", 1}, {"FramesBlind", 3000000000.0}});
        break;
      case StatusPage::Odometry:
        print_page({{"OdometryScale", 1.01234}, {"OdometryScaleError", 0.00042}, {"OdometryScaleValid", 1}});
        break;
    }
  }
}

}  // namespace

int main() {
  print_odometry();
  print_commands();
  print_loop_pages();
  print_status_pages();
  return 0;
}
