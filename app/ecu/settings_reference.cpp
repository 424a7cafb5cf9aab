#include "app/ecu/settings_reference.hpp"

#include <bit>
#include <cctype>
#include <cmath>
#include <initializer_list>
#include <sstream>

#include "app/ecu/config.hpp"
#include "app/ecu/settings.hpp"

namespace markloop::ecu {

namespace {

constexpr std::string_view kConfHeader =
    "# markloop ECU configuration: one \"key = value\" per line, '#' starts a comment.\n"
    "# Command-line flags override these (markloop --help); `markloop --config FILE\n"
    "# --print-config` shows every key with the value in force. Generated from\n"
    "# app/ecu/settings.cpp (markloop-settings --write); the reference is\n"
    "# docs/configuration.md.\n";

constexpr std::size_t kConfWidth = 79;

bool is_text(const Setting& s) {
  return s.kind == SettingKind::kPath || s.kind == SettingKind::kName;
}

// The value in the shipped file: its own where it sets one, else the default.
std::string conf_value(const Setting& s) {
  if (!s.installed.empty()) return std::string(s.installed);
  return format_config_value(EcuConfig{}, s.key);
}

// A range end: large powers of two and of ten as such.
std::string range_end(const Setting& s, double value) {
  if (s.kind == SettingKind::kInteger) {
    const auto whole = static_cast<unsigned long long>(std::fabs(value));
    if (value > 0 && whole >= (1ull << 20) && std::has_single_bit(whole))
      return "2^" + std::to_string(std::countr_zero(whole));
    return std::to_string(static_cast<long long>(value));
  }
  if (value >= 1.0e6 && std::pow(10.0, std::round(std::log10(value))) == value)
    return "10^" + std::to_string(static_cast<int>(std::round(std::log10(value))));
  std::ostringstream out;
  out << value;
  return out.str();
}

std::string range_text(const Setting& s) {
  switch (s.kind) {
    case SettingKind::kPath:
      return "path";
    case SettingKind::kName:
      return "name";
    case SettingKind::kBool:
      return "`true`, `false`";
    case SettingKind::kPixelFormat:
      return "`grey`, `yuyv`";
    case SettingKind::kInteger:
    case SettingKind::kReal:
      break;
  }
  return range_end(s, s.min) + ".." + range_end(s, s.max);
}

// `text` as '#' comment lines of at most kConfWidth characters.
std::string comment(std::string_view text) {
  std::string out;
  std::string line = "#";
  std::istringstream words{std::string(text)};
  for (std::string word; words >> word;) {
    if (line.size() + 1 + word.size() > kConfWidth) {
      out.append(line).push_back('\n');
      line.resize(1);
    }
    line.append(" ").append(word);
  }
  return out + line + "\n";
}

// The description as a sentence, with the range of a number.
std::string conf_comment(const Setting& s) {
  std::string text(s.description);
  if (!text.empty()) text[0] = static_cast<char>(std::toupper(static_cast<unsigned char>(text[0])));
  text += ".";
  if (s.kind == SettingKind::kInteger || s.kind == SettingKind::kReal) {
    text += " Range: " + range_text(s);
    if (!s.unit.empty()) text.append(" ").append(s.unit);
    text += ".";
  }
  return comment(text);
}

// "key = value", without a trailing blank when the value is empty.
std::string conf_line(const Setting& s) {
  const std::string value = conf_value(s);
  return std::string(s.key) + (value.empty() ? " =" : " = " + value) + "\n";
}

std::string conf_heading(std::string_view title) {
  std::string line = "# --- " + std::string(title) + " ";
  if (line.size() < kConfWidth) line.resize(kConfWidth, '-');
  return line + "\n";
}

// A value as the reference shows it: texts and names quoted, numbers as they are.
std::string docs_value(const Setting& s, const std::string& value) {
  if (is_text(s) && value.empty()) return "empty";
  if (s.kind == SettingKind::kInteger || s.kind == SettingKind::kReal) return value;
  return "`" + value + "`";
}

std::string docs_default(const Setting& s) {
  std::string text = docs_value(s, format_config_value(EcuConfig{}, s.key));
  if (!s.installed.empty()) text += " (installed: " + docs_value(s, std::string(s.installed)) + ")";
  return text;
}

// A Markdown table row of `cells`.
std::string table_row(std::initializer_list<std::string> cells) {
  std::string row("|");
  for (const std::string& cell : cells) row.append(cell.empty() ? " |" : " " + cell + " |");
  return row + "\n";
}

std::string quoted(std::string_view text) {
  std::string out;
  if (!text.empty()) out.append("`").append(text).append("`");
  return out;
}

std::string docs_row(const Setting& s) {
  return table_row({quoted(s.key), docs_default(s), range_text(s), std::string(s.unit),
                    std::string(s.description), quoted(s.flag)});
}

std::string docs_section(SettingSection section) {
  const SettingSectionText& text = section_text(section);
  std::string out = "## " + std::string(text.title) + "\n\n";
  if (!text.intro.empty()) out += std::string(text.intro) + "\n";
  out += "| key | default | range | unit | meaning | flag |\n|---|---|---|---|---|---|\n";
  for (const Setting& s : settings())
    if (s.section == section) out += docs_row(s);
  if (!text.notes.empty()) out.append("\n").append(text.notes);
  return out;
}

}  // namespace

std::string reference_conf() {
  std::string out(kConfHeader);
  for (int i = 0; i < kSettingSections; ++i) {
    const auto section = static_cast<SettingSection>(i);
    out.append("\n").append(conf_heading(section_text(section).title));
    for (const Setting& s : settings())
      if (s.section == section) out.append(conf_comment(s)).append(conf_line(s));
  }
  return out;
}

std::string reference_docs() {
  std::string out(kReferenceBegin);
  for (int i = 0; i < kSettingSections; ++i)
    out.append("\n").append(docs_section(static_cast<SettingSection>(i)));
  return out + "\n" + std::string(kReferenceEnd);
}

Result<std::string> with_reference_docs(std::string_view document) {
  const std::size_t begin = document.find(kReferenceBegin);
  const std::size_t end = document.find(kReferenceEnd);
  if (begin == std::string_view::npos || end == std::string_view::npos || end < begin)
    return error("no generated part: the lines '" + std::string(kReferenceBegin.substr(0, 40)) +
                 "...' and '" + std::string(kReferenceEnd.substr(0, kReferenceEnd.size() - 1)) +
                 "' are missing");
  std::string out(document.substr(0, begin));
  out += reference_docs();
  out += document.substr(end + kReferenceEnd.size());
  return out;
}

}  // namespace markloop::ecu
