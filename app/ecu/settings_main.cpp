// markloop-settings: writes the shipped markloop.conf and the keys' tables of
// docs/configuration.md from the settings table (app/ecu/settings.cpp).
#include <cstdio>
#include <string>

#include "app/common/cli.hpp"
#include "app/ecu/settings_reference.hpp"
#include "platform/files.hpp"

namespace {

constexpr const char* kUsage = R"(usage: markloop-settings --write SOURCE_DIR
       markloop-settings --print conf|docs

Writes SOURCE_DIR/app/ecu/markloop.conf and the generated part of
SOURCE_DIR/docs/configuration.md from the settings table
(app/ecu/settings.cpp), or prints either to standard output.

)";

constexpr markloop::cli::OptionSpec kOptions[] = {
    {"--write", "SOURCE_DIR", "rewrite both files in this source tree"},
    {"--print", "WHAT", "print conf (markloop.conf) or docs (the keys' tables)"},
    {"--help", "", "this text"},
};

constexpr std::size_t kMaxDocumentBytes = std::size_t{1} << 20;

void write_or_fail(const std::string& path, const std::string& text) {
  std::FILE* file = std::fopen(path.c_str(), "wb");
  const bool written = file != nullptr && std::fwrite(text.data(), 1, text.size(), file) == text.size();
  if (file != nullptr && std::fclose(file) != 0) markloop::cli::fail("cannot write " + path);
  if (!written) markloop::cli::fail("cannot write " + path);
}

void write_reference(const std::string& root) {
  const std::string docs_path = root + "/docs/configuration.md";
  std::string document;
  if (auto ec = markloop::platform::read_file_bounded(docs_path.c_str(), kMaxDocumentBytes, document))
    markloop::cli::fail(
        markloop::platform::describe_read_error(docs_path, ec, kMaxDocumentBytes, "a document"));
  markloop::Result<std::string> updated = markloop::ecu::with_reference_docs(document);
  if (!updated) markloop::cli::fail(docs_path + ": " + updated.message());
  write_or_fail(root + "/app/ecu/markloop.conf", markloop::ecu::reference_conf());
  write_or_fail(docs_path, *updated);
}

}  // namespace

int main(int argc, char** argv) {
  markloop::cli::program_name() = "markloop-settings";
  const markloop::cli::ParsedArgs args = markloop::cli::parse_args_or_fail(argc, argv, kOptions);
  if (args.help() || args.given().empty()) {
    std::fputs(kUsage, stdout);
    std::fputs(markloop::cli::options_help(kOptions).c_str(), stdout);
    return args.help() ? markloop::cli::kExitOk : markloop::cli::kExitBadInput;
  }
  if (const auto root = args.value("--write")) write_reference(std::string(*root));
  if (const auto what = args.value("--print")) {
    if (*what == "conf")
      std::fputs(markloop::ecu::reference_conf().c_str(), stdout);
    else if (*what == "docs")
      std::fputs(markloop::ecu::reference_docs().c_str(), stdout);
    else
      markloop::cli::fail("--print: conf or docs, got '" + std::string(*what) + "'");
  }
  return markloop::cli::kExitOk;
}
