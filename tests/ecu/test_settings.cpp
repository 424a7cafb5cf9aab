// The settings table: its rows are consistent, its ranges lie within the
// engine's own checks, and the shipped markloop.conf and the reference in
// docs/configuration.md are what it generates.
#include <catch2/catch_test_macros.hpp>
#include <catch2/matchers/catch_matchers_string.hpp>

#include <fstream>
#include <set>
#include <sstream>
#include <string>

#include "app/ecu/config.hpp"
#include "app/ecu/settings.hpp"
#include "app/ecu/settings_reference.hpp"

using Catch::Matchers::StartsWith;
using markloop::ecu::EcuConfig;
using markloop::ecu::Setting;
using markloop::ecu::SettingKind;

namespace {

std::string read_source(const std::string& relative) {
  std::ifstream in(std::string(MARKLOOP_SOURCE_DIR) + "/" + relative, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// The first line where `committed` and `generated` differ, empty when none.
std::string first_difference(const std::string& committed, const std::string& generated) {
  std::istringstream a(committed);
  std::istringstream b(generated);
  std::string line_a;
  std::string line_b;
  for (int number = 1;; ++number) {
    const bool more_a = static_cast<bool>(std::getline(a, line_a));
    const bool more_b = static_cast<bool>(std::getline(b, line_b));
    if (!more_a && !more_b) return committed == generated ? std::string() : "the last line's end";
    if (!more_a || !more_b || line_a != line_b)
      return "line " + std::to_string(number) + ": committed '" + (more_a ? line_a : "(end)") +
             "', generated '" + (more_b ? line_b : "(end)") + "'";
  }
}

bool is_number(const Setting& s) {
  return s.kind == SettingKind::kInteger || s.kind == SettingKind::kReal;
}

std::string number_text(const Setting& s, double value) {
  if (s.kind == SettingKind::kInteger) return std::to_string(static_cast<long long>(value));
  std::ostringstream out;
  out.precision(17);
  out << value;
  return out.str();
}

// `config` with every engine number at its least (or greatest) accepted value.
EcuConfig engine_at_limit(bool greatest) {
  EcuConfig config;
  for (const Setting& s : markloop::ecu::settings()) {
    if (!is_number(s) || !(s.key.starts_with("engine.") || s.key.starts_with("database."))) continue;
    REQUIRE(markloop::ecu::set_config_value(config, s.key, number_text(s, greatest ? s.max : s.min)));
  }
  return config;
}

}  // namespace

TEST_CASE("the shipped markloop.conf and the reference are what the settings table generates") {
  INFO("regenerate both from the source tree's root: " << markloop::ecu::kRegenerateCommand);
  CHECK(first_difference(read_source("app/ecu/markloop.conf"), markloop::ecu::reference_conf()) == "");
  const std::string document = read_source("docs/configuration.md");
  const markloop::Result<std::string> expected = markloop::ecu::with_reference_docs(document);
  REQUIRE(expected.ok());
  CHECK(first_difference(document, *expected) == "");
}

TEST_CASE("the reference needs its markers") {
  const markloop::Result<std::string> missing = markloop::ecu::with_reference_docs("# no tables\n");
  REQUIRE_FALSE(missing.ok());
  CHECK_THAT(missing.message(), StartsWith("no generated part"));
}

TEST_CASE("every setting has one key, one flag, a range holding its default and a description") {
  std::set<std::string_view> keys;
  std::set<std::string_view> flags;
  const EcuConfig defaults;
  for (const Setting& s : markloop::ecu::settings()) {
    INFO(s.key);
    CHECK(keys.insert(s.key).second);
    CHECK(markloop::ecu::find_setting(s.key) == &s);
    if (!s.flag.empty()) {
      CHECK(flags.insert(s.flag).second);
      CHECK(markloop::ecu::find_setting_by_flag(s.flag) == &s);
    }
    CHECK_FALSE(s.description.empty());
    if (is_number(s)) CHECK(s.min <= s.max);
    // The default and the shipped value are accepted and read back as given.
    EcuConfig config;
    const std::string value = markloop::ecu::format_config_value(defaults, s.key);
    REQUIRE(markloop::ecu::set_config_value(config, s.key, value));
    CHECK(markloop::ecu::format_config_value(config, s.key) == value);
    if (!s.installed.empty()) {
      REQUIRE(markloop::ecu::set_config_value(config, s.key, s.installed));
      CHECK(markloop::ecu::format_config_value(config, s.key) == s.installed);
    }
  }
  CHECK(keys.size() == markloop::ecu::settings().size());
}

TEST_CASE("a number outside its range is refused naming the key and the range") {
  for (const Setting& s : markloop::ecu::settings()) {
    if (!is_number(s)) continue;
    INFO(s.key);
    EcuConfig config;
    const std::string below = number_text(s, s.min - 1);
    const markloop::Status status = markloop::ecu::set_config_value(config, s.key, below);
    REQUIRE_FALSE(status.ok());
    CHECK_THAT(status.message(), StartsWith(std::string(s.key) + ": must be between "));
    CHECK_FALSE(markloop::ecu::set_config_value(config, s.key, "x").ok());
  }
}

TEST_CASE("the engine's ranges in the table lie within the engine's own checks") {
  // Cross-field checks (the longest link above the row width) hold at both
  // ends; each limit alone, from the ECU's defaults, passes as well.
  CHECK(validate(engine_at_limit(false).engine) == nullptr);
  CHECK(validate(engine_at_limit(true).engine) == nullptr);
  for (const Setting& s : markloop::ecu::settings()) {
    if (!is_number(s) || !(s.key.starts_with("engine.") || s.key.starts_with("database."))) continue;
    for (const double limit : {s.min, s.max}) {
      EcuConfig config;
      if (s.key == "engine.max_link_m") config.engine.chain.row_width_m = 0.0;
      REQUIRE(markloop::ecu::set_config_value(config, s.key, number_text(s, limit)));
      INFO(s.key << " = " << number_text(s, limit));
      CHECK(validate(config.engine) == nullptr);
    }
  }
}
