// What every command-line program shares: one option parser driven by a
// table that also writes the --help text, uniform error messages
// ("PROGRAM: what is wrong"), the exit statuses, and strict number parsing
// (files: app/tools/common/tool_files.hpp). Not for the real-time loop.
#pragma once

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "app/common/result.hpp"

namespace markloop::cli {

inline const char*& program_name() {
  static const char* name = "markloop";
  return name;
}

// The exit statuses of every program.
enum ExitStatus : int {
  kExitOk = 0,
  kExitOutputFailed = 1,  // a result could not be written or sent
  kExitBadInput = 2,      // bad options or input; nothing was run, or the run stopped
};

[[noreturn]] inline void fail(const std::string& message) {
  std::fprintf(stderr, "%s: %s\n", program_name(), message.c_str());
  std::exit(kExitBadInput);
}

// One option of a program. An option with a value_name takes a value
// ("--map FILE"); one without is a flag. The table is also the help text.
struct OptionSpec {
  std::string_view name;        // "--map"
  std::string_view value_name;  // "FILE", or empty for a flag
  std::string_view help;        // one line
};

// What parse_args found, in the order given.
class ParsedArgs {
 public:
  struct Given {
    std::string_view name;
    std::string_view value;  // empty for a flag
  };

  bool help() const { return help_; }
  bool has(std::string_view name) const {
    for (const Given& g : given_)
      if (g.name == name) return true;
    return false;
  }
  // The last value given for `name`.
  std::optional<std::string_view> value(std::string_view name) const {
    std::optional<std::string_view> last;
    for (const Given& g : given_)
      if (g.name == name) last = g.value;
    return last;
  }
  const std::vector<Given>& given() const { return given_; }
  const std::vector<std::string_view>& positional() const { return positional_; }

 private:
  friend Result<ParsedArgs> parse_args(std::span<char* const>, std::span<const OptionSpec>, std::size_t,
                                       std::size_t);
  bool help_ = false;
  std::vector<Given> given_;
  std::vector<std::string_view> positional_;
};

// Parses args (argv without the program name) against `options`. "--help"
// and "-h" set help() and end parsing. Between min_positional and
// max_positional arguments that do not start with "-" are accepted.
inline Result<ParsedArgs> parse_args(std::span<char* const> args, std::span<const OptionSpec> options,
                                     std::size_t min_positional = 0, std::size_t max_positional = 0) {
  ParsedArgs parsed;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string_view arg = args[i];
    if (arg == "--help" || arg == "-h") {
      parsed.help_ = true;
      return parsed;
    }
    const OptionSpec* spec = nullptr;
    for (const OptionSpec& o : options)
      if (o.name == arg) spec = &o;
    if (spec == nullptr) {
      if (arg.starts_with("-") && arg.size() > 1)
        return error("unknown option " + std::string(arg) + " (see --help)");
      if (parsed.positional_.size() >= max_positional)
        return error("unexpected argument " + std::string(arg) + " (see --help)");
      parsed.positional_.push_back(arg);
      continue;
    }
    if (spec->value_name.empty()) {
      parsed.given_.push_back({spec->name, {}});
      continue;
    }
    if (i + 1 >= args.size()) return error(std::string(arg) + " needs a value (see --help)");
    // "--map --quiet" is a forgotten value, not a file named "--quiet".
    if (std::string_view(args[i + 1]).starts_with("--"))
      return error(std::string(arg) + " needs a value, got the option " + args[i + 1] + " (see --help)");
    parsed.given_.push_back({spec->name, args[++i]});
  }
  if (parsed.positional_.size() < min_positional) return error("missing argument (see --help)");
  return parsed;
}

// parse_args over main's arguments; bad options fail with exit status 2.
inline ParsedArgs parse_args_or_fail(int argc, char** argv, std::span<const OptionSpec> options,
                                     std::size_t min_positional = 0, std::size_t max_positional = 0) {
  Result<ParsedArgs> parsed = parse_args(std::span<char* const>(argv + 1, static_cast<std::size_t>(argc - 1)),
                                         options, min_positional, max_positional);
  if (!parsed) fail(parsed.message());
  return std::move(parsed).value();
}

// The options part of a --help text: one line per option, aligned.
inline std::string options_help(std::span<const OptionSpec> options) {
  std::size_t width = 0;
  for (const OptionSpec& o : options)
    width = std::max(width, o.name.size() + (o.value_name.empty() ? 0 : o.value_name.size() + 1));
  std::string text;
  for (const OptionSpec& o : options) {
    std::string left = "  ";
    left.append(o.name);
    if (!o.value_name.empty()) left.append(" ").append(o.value_name);
    left.resize(width + 4, ' ');
    text.append(left).append(o.help).append("\n");
  }
  return text;
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
