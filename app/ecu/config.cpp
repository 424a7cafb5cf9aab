#include "app/ecu/config.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <sstream>
#include <type_traits>
#include <vector>

#include "platform/files.hpp"

namespace markloop::ecu {

namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

bool parse_double(std::string_view text, double& out) {
  const std::string copy(text);
  char* end = nullptr;
  errno = 0;
  const double value = std::strtod(copy.c_str(), &end);
  if (copy.empty() || end != copy.c_str() + copy.size() || errno != 0 || !std::isfinite(value)) return false;
  out = value;
  return true;
}

bool parse_int(std::string_view text, long long& out) {
  const auto* first = text.data();
  const auto* last = text.data() + text.size();
  const auto result = std::from_chars(first, last, out);
  return !text.empty() && result.ec == std::errc{} && result.ptr == last;
}

bool parse_bool(std::string_view text, bool& out) {
  if (text == "true" || text == "yes" || text == "on" || text == "1") {
    out = true;
    return true;
  }
  if (text == "false" || text == "no" || text == "off" || text == "0") {
    out = false;
    return true;
  }
  return false;
}

using Setter = std::function<std::string(EcuConfig&, std::string_view)>;
using Getter = std::function<std::string(const EcuConfig&)>;

struct Key {
  const char* name;
  Setter set;
  Getter get;
};

Key text_key(const char* name, std::string EcuConfig::*field) {
  return {name,
          [field](EcuConfig& c, std::string_view v) {
            c.*field = std::string(v);
            return std::string();
          },
          [field](const EcuConfig& c) { return c.*field; }};
}

template <typename Section>
Key text_key(const char* name, Section EcuConfig::*section, std::string Section::*field) {
  return {name,
          [section, field](EcuConfig& c, std::string_view v) {
            c.*section.*field = std::string(v);
            return std::string();
          },
          [section, field](const EcuConfig& c) { return c.*section.*field; }};
}

// Integer settings: `get`/`put` reach the field, [low, high] is the accepted range.
template <typename Get>
Key integer_key(const char* name, long long low, long long high, Get field) {
  return {name,
          [=](EcuConfig& c, std::string_view v) {
            long long value = 0;
            if (!parse_int(v, value)) return "not a whole number: '" + std::string(v) + "'";
            if (value < low || value > high)
              return "must be between " + std::to_string(low) + " and " + std::to_string(high) + ", got " +
                     std::string(v);
            using T = std::remove_reference_t<decltype(field(c))>;
            field(c) = static_cast<T>(value);
            return std::string();
          },
          [=](const EcuConfig& c) {
            auto& mutable_config = const_cast<EcuConfig&>(c);
            return std::to_string(field(mutable_config));
          }};
}

template <typename Get>
Key real_key(const char* name, double low, double high, Get field) {
  return {name,
          [=](EcuConfig& c, std::string_view v) {
            double value = 0.0;
            if (!parse_double(v, value)) return "not a number: '" + std::string(v) + "'";
            if (value < low || value > high) {
              std::ostringstream s;
              s << "must be between " << low << " and " << high << ", got " << v;
              return s.str();
            }
            using T = std::remove_reference_t<decltype(field(c))>;
            field(c) = static_cast<T>(value);
            return std::string();
          },
          [=](const EcuConfig& c) {
            std::ostringstream s;
            s << field(const_cast<EcuConfig&>(c));
            return s.str();
          }};
}

template <typename Get>
Key bool_key(const char* name, Get field) {
  return {
      name,
      [=](EcuConfig& c, std::string_view v) {
        bool value = false;
        if (!parse_bool(v, value)) return "not true/false: '" + std::string(v) + "'";
        field(c) = value;
        return std::string();
      },
      [=](const EcuConfig& c) { return std::string(field(const_cast<EcuConfig&>(c)) ? "true" : "false"); }};
}

const std::vector<Key>& keys() {
  static const std::vector<Key> table = {
      text_key("camera.device", &EcuConfig::camera, &CameraSettings::device),
      text_key("camera.file", &EcuConfig::camera, &CameraSettings::file),
      integer_key("camera.input", -1, 64, [](EcuConfig& c) -> int& { return c.camera.input; }),
      {"camera.format",
       [](EcuConfig& c, std::string_view v) {
         if (v == "grey" || v == "GREY")
           c.camera.format = PixelFormat::kGrey;
         else if (v == "yuyv" || v == "YUYV")
           c.camera.format = PixelFormat::kYuyv;
         else
           return "must be grey or yuyv, got '" + std::string(v) + "'";
         return std::string();
       },
       [](const EcuConfig& c) {
         return std::string(c.camera.format == PixelFormat::kGrey ? "grey" : "yuyv");
       }},
      integer_key("camera.width", 16, 8192, [](EcuConfig& c) -> unsigned& { return c.camera.width; }),
      integer_key("camera.height", 16, 8192, [](EcuConfig& c) -> unsigned& { return c.camera.height; }),
      integer_key("camera.fps", 0, 240, [](EcuConfig& c) -> unsigned& { return c.camera.fps; }),
      integer_key("camera.max_rate", 0, 240, [](EcuConfig& c) -> unsigned& { return c.camera.max_rate; }),
      integer_key("camera.timeout_ms", 10, 60000,
                  [](EcuConfig& c) -> unsigned& { return c.camera.timeout_ms; }),
      integer_key("camera.blind_frames", 1, 100000,
                  [](EcuConfig& c) -> unsigned& { return c.camera.blind_frames; }),
      text_key("calibration", &EcuConfig::calibration),
      text_key("can.interface", &EcuConfig::can, &CanSettings::interface),
      text_key("can.in_log", &EcuConfig::can, &CanSettings::in_log),
      text_key("can.out_log", &EcuConfig::can, &CanSettings::out_log),
      text_key("map.file", &EcuConfig::map_file),
      bool_key("map.save_on_exit", [](EcuConfig& c) -> bool& { return c.save_map_on_exit; }),
      text_key("detections_out", &EcuConfig::detections_out),
      text_key("landmarks_out", &EcuConfig::landmarks_out),
      integer_key("status.period_ms", 10, 10000,
                  [](EcuConfig& c) -> unsigned& { return c.status_period_ms; }),
      integer_key("odometry.timeout_ms", 20, 10000,
                  [](EcuConfig& c) -> unsigned& { return c.odometry_timeout_ms; }),
      bool_key("file.realtime", [](EcuConfig& c) -> bool& { return c.realtime_replay; }),
      integer_key("file.first_frame", 0, std::int64_t{1} << 40,
                  [](EcuConfig& c) -> std::uint64_t& { return c.first_frame; }),
      integer_key("file.frames", 0, std::int64_t{1} << 40,
                  [](EcuConfig& c) -> std::uint64_t& { return c.frame_count; }),
      integer_key("realtime.priority", 0, 99, [](EcuConfig& c) -> int& { return c.realtime.priority; }),
      integer_key("realtime.cpu", -1, 1023, [](EcuConfig& c) -> int& { return c.realtime.cpu; }),
      bool_key("realtime.mlockall", [](EcuConfig& c) -> bool& { return c.realtime.lock_memory; }),
      real_key("observation.min_score", 0.0, 1.0, [](EcuConfig& c) -> float& { return c.gate.min_score; }),
      real_key("observation.min_range_m", 0.0, 100.0,
               [](EcuConfig& c) -> float& { return c.gate.min_range_m; }),
      real_key("observation.max_range_m", 0.0, 100.0,
               [](EcuConfig& c) -> float& { return c.gate.max_range_m; }),
      integer_key("engine.k", 2, kMaxSequenceLength,
                  [](EcuConfig& c) -> unsigned& { return c.engine.chain.k; }),
      real_key("engine.association_radius_m", 0.01, 100.0,
               [](EcuConfig& c) -> double& { return c.engine.tracker.association_radius_m; }),
      real_key("engine.commit_after_s", 0.01, 100.0,
               [](EcuConfig& c) -> double& { return c.engine.tracker.commit_after_s; }),
      integer_key("engine.min_observations", 1, 1000,
                  [](EcuConfig& c) -> unsigned& { return c.engine.tracker.min_observations; }),
      real_key("engine.release_lag_m", 0.0, 1000.0,
               [](EcuConfig& c) -> double& { return c.engine.tracker.release_lag_m; }),
      real_key("engine.row_width_m", 0.0, 100.0,
               [](EcuConfig& c) -> double& { return c.engine.chain.row_width_m; }),
      real_key("engine.max_link_m", 0.1, 100000.0,
               [](EcuConfig& c) -> double& { return c.engine.chain.max_link_m; }),
      integer_key("engine.max_skipped_rows", 0, 1,
                  [](EcuConfig& c) -> unsigned& { return c.engine.chain.max_skipped_rows; }),
      real_key("engine.distance_tolerance_m", 0.001, 100.0,
               [](EcuConfig& c) -> double& { return c.engine.match.distance_tolerance_abs_m; }),
      real_key("engine.distance_tolerance_rel", 0.0, 0.1,
               [](EcuConfig& c) -> double& { return c.engine.match.distance_tolerance_rel; }),
      real_key("engine.min_separation_m", 0.0, 1.0e6,
               [](EcuConfig& c) -> double& { return c.engine.match.min_separation_m; }),
      real_key("engine.min_separation_s", 0.0, 1.0e6,
               [](EcuConfig& c) -> double& { return c.engine.match.min_separation_s; }),
      real_key("engine.max_residual_m", 0.001, 100.0,
               [](EcuConfig& c) -> double& { return c.engine.match.max_residual_m; }),
      real_key("engine.max_frame_distance_m", 0.0, 1.0e6,
               [](EcuConfig& c) -> double& { return c.engine.match.max_frame_distance_m; }),
      real_key("engine.max_drift_rel", 0.0, 1.0,
               [](EcuConfig& c) -> double& { return c.engine.match.max_drift_rel; }),
      real_key("engine.max_drift_m", 0.0, 1.0e6,
               [](EcuConfig& c) -> double& { return c.engine.match.max_drift_abs_m; }),
      real_key("engine.max_drift_yaw_deg", 0.0, 360.0,
               [](EcuConfig& c) -> double& { return c.engine.match.max_drift_yaw_abs_deg; }),
      real_key("engine.max_drift_yaw_deg_per_m", 0.0, 10.0,
               [](EcuConfig& c) -> double& { return c.engine.match.max_drift_yaw_rel_deg_per_m; }),
      bool_key("engine.confirm_loaded_places",
               [](EcuConfig& c) -> bool& { return c.engine.match.confirm_loaded_places; }),
      real_key("engine.confirm_min_gap_m", 0.0, 1.0e6,
               [](EcuConfig& c) -> double& { return c.engine.match.confirm_min_gap_m; }),
      real_key("engine.confirm_within_m", 0.0, 1.0e6,
               [](EcuConfig& c) -> double& { return c.engine.match.confirm_within_m; }),
      integer_key("engine.max_candidates", 1, 100000,
                  [](EcuConfig& c) -> unsigned& { return c.engine.match.max_candidates_per_query; }),
      integer_key("database.landmark_capacity", 16, std::int64_t{1} << 30,
                  [](EcuConfig& c) -> std::size_t& { return c.engine.database.landmark_capacity; }),
      integer_key("database.sequence_capacity", 16, std::int64_t{1} << 30,
                  [](EcuConfig& c) -> std::size_t& { return c.engine.database.sequence_capacity; }),
  };
  return table;
}

}  // namespace

std::string set_config_value(EcuConfig& config, std::string_view key, std::string_view value) {
  for (const Key& k : keys()) {
    if (key == k.name) {
      const std::string error = k.set(config, value);
      return error.empty() ? error : std::string(key) + ": " + error;
    }
  }
  return "unknown key '" + std::string(key) + "'";
}

std::string load_config_file(const std::string& path, EcuConfig& config) {
  std::string content;
  if (auto ec = platform::read_file_bounded(path.c_str(), kMaxConfigFileBytes, content))
    return platform::describe_read_error(path, ec, kMaxConfigFileBytes, "a configuration file");
  std::string_view rest(content);
  for (unsigned number = 1; !rest.empty(); ++number) {
    const std::size_t end = std::min(rest.find('\n'), rest.size());
    const std::string_view line = rest.substr(0, end);
    rest.remove_prefix(std::min(end + 1, rest.size()));
    std::string_view text = line;
    if (const auto hash = text.find('#'); hash != std::string_view::npos) text = text.substr(0, hash);
    text = trim(text);
    if (text.empty()) continue;
    const auto equals = text.find('=');
    const std::string where = path + ":" + std::to_string(number) + ": ";
    if (equals == std::string_view::npos)
      return where + "expected 'key = value', got '" + std::string(line) + "'";
    const std::string_view key = trim(text.substr(0, equals));
    const std::string_view value = trim(text.substr(equals + 1));
    if (key.empty()) return where + "missing key before '='";
    const std::string error = set_config_value(config, key, value);
    if (!error.empty()) return where + error;
  }
  return {};
}

std::string validate_config(const EcuConfig& config) {
  if (const char* engine_error = validate(config.engine)) return std::string("engine: ") + engine_error;
  const bool camera_file = !config.camera.file.empty();
  const bool can_file = !config.can.in_log.empty();
  if (camera_file != can_file)
    return "file mode needs both a frame file (--camera-file) and a CAN log (--can-in)";
  if (!camera_file && config.camera.device.empty()) return "no camera device or frame file";
  if (!camera_file && config.can.interface.empty()) return "no CAN interface or log file";
  if (config.realtime_replay && !camera_file) return "--realtime is for file mode only";
  if (config.gate.min_range_m >= config.gate.max_range_m)
    return "observation.min_range_m must be below observation.max_range_m";
  return {};
}

std::string format_config(const EcuConfig& config) {
  std::string out;
  for (const Key& k : keys()) out += std::string(k.name) + " = " + k.get(config) + "\n";
  return out;
}

}  // namespace markloop::ecu
