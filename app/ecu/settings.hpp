// Every setting of the ECU program, declared once: key, kind, range, unit,
// section, the command-line flag that sets it, the value the shipped
// markloop.conf gives it where that differs from the default, its
// description and the member of EcuConfig it sets. The default is the
// member's initializer (app/ecu/config.hpp, ecu_engine_defaults()). The
// parser (config.cpp), markloop.conf and docs/configuration.md
// (settings_reference.cpp, checked by tests/ecu/test_settings.cpp) all come
// from this table.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <variant>

#include "app/ecu/config.hpp"

namespace markloop::ecu {

enum class SettingKind : std::uint8_t {
  kPath,         // a file or device path; empty allowed
  kName,         // a name (an interface); empty allowed
  kInteger,      // whole number within [min, max]
  kReal,         // finite number within [min, max]
  kBool,         // true/yes/on/1 or false/no/off/0
  kPixelFormat,  // grey or yuyv
};

// The sections of markloop.conf and of the reference, in their order.
enum class SettingSection : std::uint8_t {
  kCamera,
  kCan,
  kMap,
  kObservation,
  kEngine,
  kRealtime,
  kOutputs,
};
inline constexpr int kSettingSections = 7;

// A setting's value on its way into or out of EcuConfig.
using SettingValue = std::variant<std::string, long long, double, bool>;

// Reads and writes one member of EcuConfig.
struct SettingMember {
  SettingValue (*read)(const EcuConfig&);
  void (*write)(EcuConfig&, const SettingValue&);
};

// The member `F` returns, for `[](auto& c) -> auto& { return c.camera.width; }`.
template <class F>
constexpr SettingMember member(F) {
  using T = std::remove_reference_t<std::invoke_result_t<F, EcuConfig&>>;
  return {[](const EcuConfig& c) -> SettingValue {
            const T& field = F{}(c);
            if constexpr (std::is_same_v<T, std::string> || std::is_same_v<T, bool>)
              return field;
            else if constexpr (std::is_floating_point_v<T>)
              return static_cast<double>(field);
            else
              return static_cast<long long>(field);
          },
          [](EcuConfig& c, const SettingValue& value) {
            T& field = F{}(c);
            if constexpr (std::is_same_v<T, std::string> || std::is_same_v<T, bool>)
              field = std::get<T>(value);
            else if constexpr (std::is_floating_point_v<T>)
              field = static_cast<T>(std::get<double>(value));
            else
              field = static_cast<T>(std::get<long long>(value));
          }};
}

struct Setting {
  std::string_view key{};
  SettingKind kind{};
  SettingMember member{};
  double min = 0.0;  // kInteger, kReal: inclusive range
  double max = 0.0;
  std::string_view unit{};
  SettingSection section{};
  std::string_view flag{};       // the command-line option that sets it, if any
  std::string_view installed{};  // its value in the shipped markloop.conf; empty: the default
  std::string_view description{};
};

// Every setting, in the order --print-config lists them.
std::span<const Setting> settings();
// The setting named `key`, or nullptr.
const Setting* find_setting(std::string_view key);
// The setting the command-line option `flag` sets, or nullptr.
const Setting* find_setting_by_flag(std::string_view flag);

struct SettingSectionText {
  std::string_view title{};  // heading in markloop.conf and the reference
  std::string_view intro{};  // reference only, before the table (Markdown)
  std::string_view notes{};  // reference only, after the table (Markdown)
};
const SettingSectionText& section_text(SettingSection section);

}  // namespace markloop::ecu
