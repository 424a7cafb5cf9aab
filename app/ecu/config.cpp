#include "app/ecu/config.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <sstream>

#include "app/ecu/settings.hpp"
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

// The pixel formats by name; upper case is accepted as V4L2 spells them.
constexpr std::string_view kPixelFormatNames[] = {"grey", "yuyv"};
constexpr std::string_view kPixelFormatUpper[] = {"GREY", "YUYV"};

std::string range_error(const Setting& s, std::string_view text) {
  std::ostringstream out;
  if (s.kind == SettingKind::kInteger)
    out << "must be between " << static_cast<long long>(s.min) << " and " << static_cast<long long>(s.max);
  else
    out << "must be between " << s.min << " and " << s.max;
  out << ", got " << text;
  return out.str();
}

Result<SettingValue> parse_integer(const Setting& s, std::string_view text) {
  long long value = 0;
  if (!parse_int(text, value)) return error("not a whole number: '" + std::string(text) + "'");
  if (value < static_cast<long long>(s.min) || value > static_cast<long long>(s.max))
    return error(range_error(s, text));
  return SettingValue(value);
}

Result<SettingValue> parse_real(const Setting& s, std::string_view text) {
  double value = 0.0;
  if (!parse_double(text, value)) return error("not a number: '" + std::string(text) + "'");
  if (value < s.min || value > s.max) return error(range_error(s, text));
  return SettingValue(value);
}

Result<SettingValue> parse_pixel_format(std::string_view text) {
  for (std::size_t i = 0; i < std::size(kPixelFormatNames); ++i)
    if (text == kPixelFormatNames[i] || text == kPixelFormatUpper[i])
      return SettingValue(static_cast<long long>(i));
  return error("must be grey or yuyv, got '" + std::string(text) + "'");
}

// `text` as a value of setting `s`, or what is wrong with it.
Result<SettingValue> parse_setting(const Setting& s, std::string_view text) {
  switch (s.kind) {
    case SettingKind::kInteger:
      return parse_integer(s, text);
    case SettingKind::kReal:
      return parse_real(s, text);
    case SettingKind::kBool: {
      bool value = false;
      if (!parse_bool(text, value)) return error("not true/false: '" + std::string(text) + "'");
      return SettingValue(value);
    }
    case SettingKind::kPixelFormat:
      return parse_pixel_format(text);
    case SettingKind::kPath:
    case SettingKind::kName:
      break;
  }
  return SettingValue(std::string(text));
}

std::string format_setting(const Setting& s, const EcuConfig& config) {
  const SettingValue value = s.member.read(config);
  if (s.kind == SettingKind::kPixelFormat)
    return std::string(kPixelFormatNames[static_cast<std::size_t>(std::get<long long>(value))]);
  if (const auto* text = std::get_if<std::string>(&value)) return *text;
  if (const auto* flag = std::get_if<bool>(&value)) return *flag ? "true" : "false";
  if (const auto* integer = std::get_if<long long>(&value)) return std::to_string(*integer);
  std::ostringstream out;
  out << std::get<double>(value);
  return out.str();
}

// One line of a configuration file: a comment, blank, or "key = value".
Status load_config_line(std::string_view line, EcuConfig& config) {
  std::string_view text = line;
  if (const auto hash = text.find('#'); hash != std::string_view::npos) text = text.substr(0, hash);
  text = trim(text);
  if (text.empty()) return {};
  const auto equals = text.find('=');
  if (equals == std::string_view::npos)
    return error("expected 'key = value', got '" + std::string(line) + "'");
  const std::string_view key = trim(text.substr(0, equals));
  if (key.empty()) return error("missing key before '='");
  return set_config_value(config, key, trim(text.substr(equals + 1)));
}

}  // namespace

Status set_config_value(EcuConfig& config, std::string_view key, std::string_view value) {
  const Setting* setting = find_setting(key);
  if (setting == nullptr) return error("unknown key '" + std::string(key) + "'");
  Result<SettingValue> parsed = parse_setting(*setting, value);
  if (!parsed) return with_context(std::string(key), parsed.error());
  setting->member.write(config, *parsed);
  return {};
}

Status load_config_file(const std::string& path, EcuConfig& config) {
  std::string content;
  if (auto ec = platform::read_file_bounded(path.c_str(), kMaxConfigFileBytes, content))
    return error(platform::describe_read_error(path, ec, kMaxConfigFileBytes, "a configuration file"));
  std::string_view rest(content);
  for (unsigned number = 1; !rest.empty(); ++number) {
    const std::size_t end = std::min(rest.find('\n'), rest.size());
    const std::string_view line = rest.substr(0, end);
    rest.remove_prefix(std::min(end + 1, rest.size()));
    if (Status status = load_config_line(line, config); !status)
      return with_context(path + ":" + std::to_string(number), status.error());
  }
  return {};
}

Status validate_config(const EcuConfig& config) {
  if (const char* engine_error = validate(config.engine))
    return error(std::string("engine: ") + engine_error);
  const bool camera_file = !config.camera.file.empty();
  const bool can_file = !config.can.in_log.empty();
  if (camera_file != can_file)
    return error("file mode needs both a frame file (--camera-file) and a CAN log (--can-in)");
  if (!camera_file && config.camera.device.empty()) return error("no camera device or frame file");
  if (!camera_file && config.can.interface.empty()) return error("no CAN interface or log file");
  if (config.realtime_replay && !camera_file) return error("--realtime is for file mode only");
  if (config.gate.min_range_m >= config.gate.max_range_m)
    return error("observation.min_range_m must be below observation.max_range_m");
  return {};
}

std::string format_config(const EcuConfig& config) {
  std::string out;
  for (const Setting& s : settings()) out += std::string(s.key) + " = " + format_setting(s, config) + "\n";
  return out;
}

std::string format_config_value(const EcuConfig& config, std::string_view key) {
  const Setting* setting = find_setting(key);
  return setting == nullptr ? std::string() : format_setting(*setting, config);
}

}  // namespace markloop::ecu
