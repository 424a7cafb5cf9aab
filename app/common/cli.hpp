// Small helpers shared by the command-line programs: uniform error messages
// ("PROGRAM: what is wrong", exit status 2) and strict number parsing (files:
// tool_files.hpp). Not for the real-time loop.
#pragma once

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <initializer_list>
#include <string>
#include <string_view>

namespace markloop::cli {

inline const char*& program_name() {
  static const char* name = "markloop";
  return name;
}

[[noreturn]] inline void fail(const std::string& message) {
  std::fprintf(stderr, "%s: %s\n", program_name(), message.c_str());
  std::exit(2);
}

// The value after the option argv[i], i moved onto it. `value_options`
// lists the program's options that take a value: any other is unknown, and
// one given last lacks its value; either fails saying so.
inline const char* option_value(int argc, char** argv, int& i,
                                std::initializer_list<std::string_view> value_options) {
  const std::string_view option = argv[i];
  bool known = false;
  for (std::string_view o : value_options) known = known || o == option;
  if (!known)
    fail((option.starts_with("-") ? "unknown option " : "unexpected argument ") + std::string(option) +
         " (see --help)");
  if (i + 1 >= argc) fail(std::string(option) + " needs a value (see --help)");
  // "--map --quiet" is a forgotten value, not a file named "--quiet".
  if (std::string_view(argv[i + 1]).starts_with("--"))
    fail(std::string(option) + " needs a value, got the option " + argv[i + 1] + " (see --help)");
  return argv[++i];
}

inline double parse_number(std::string_view option, const char* text) {
  char* end = nullptr;
  errno = 0;
  const double value = std::strtod(text, &end);
  if (end == text || *end != '\0' || errno != 0 || !std::isfinite(value))
    fail(std::string(option) + ": not a number: '" + text + "'");
  return value;
}

inline unsigned parse_whole(std::string_view option, const char* text) {
  const double value = parse_number(option, text);
  if (value < 0 || value != std::floor(value) || value > 4e9)
    fail(std::string(option) + ": not a whole number: '" + text + "'");
  return static_cast<unsigned>(value);
}

}  // namespace markloop::cli
