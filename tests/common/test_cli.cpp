#include "app/common/cli.hpp"

#include <array>
#include <catch2/catch_test_macros.hpp>
#include <string>
#include <vector>

namespace {

using markloop::cli::OptionSpec;

constexpr std::array<OptionSpec, 3> kOptions{{
    {"--map", "FILE", "the map"},
    {"--set", "KEY=VALUE", "a setting"},
    {"--quiet", "", "no report"},
}};

markloop::Result<markloop::cli::ParsedArgs> parse(std::vector<std::string> words,
                                                  std::size_t max_positional = 0) {
  static std::vector<std::string> storage;
  static std::vector<char*> argv;
  storage = std::move(words);
  argv.clear();
  for (std::string& w : storage) argv.push_back(w.data());
  return markloop::cli::parse_args(argv, kOptions, 0, max_positional);
}

}  // namespace

TEST_CASE("options are found with their values, in the order given") {
  const auto parsed = parse({"--set", "a=1", "--quiet", "--map", "m.bin", "--set", "b=2"});
  REQUIRE(parsed.ok());
  CHECK(parsed->has("--quiet"));
  CHECK(parsed->value("--map") == "m.bin");
  CHECK(parsed->value("--set") == "b=2");
  REQUIRE(parsed->given().size() == 4);
  CHECK(parsed->given()[0].value == "a=1");
  CHECK_FALSE(parsed->value("--other").has_value());
}

TEST_CASE("bad options are named") {
  CHECK(parse({"--mpa", "x"}).message() == "unknown option --mpa (see --help)");
  CHECK(parse({"stray"}).message() == "unexpected argument stray (see --help)");
  CHECK(parse({"--map"}).message() == "--map needs a value (see --help)");
  CHECK(parse({"--map", "--quiet"}).message() == "--map needs a value, got the option --quiet (see --help)");
}

TEST_CASE("help ends parsing and positional arguments are bounded") {
  CHECK(parse({"--mpa", "-h"}).ok() == false);
  CHECK(parse({"-h", "--mpa"})->help());
  const auto two = parse({"a", "--quiet", "b"}, 2);
  REQUIRE(two.ok());
  CHECK(two->positional().size() == 2);
  CHECK_FALSE(parse({"a", "b", "c"}, 2).ok());
}

TEST_CASE("the help text lists every option, aligned") {
  const std::string help = markloop::cli::options_help(kOptions);
  CHECK(help ==
        "  --map FILE       the map\n"
        "  --set KEY=VALUE  a setting\n"
        "  --quiet          no report\n");
}
