// The ECU's configuration file: any bytes load or give "FILE:LINE: what";
// a file that loads and validates prints (--print-config) as a file that
// loads to the same configuration.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "app/ecu/config.hpp"
#include "tests/fuzz/fuzz_input.hpp"

using markloop::ecu::EcuConfig;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const markloop::fuzz::InputFile file(data, size, ".conf");
  EcuConfig config;
  const markloop::Status loaded = markloop::ecu::load_config_file(file.path(), config);
  if (!loaded) {
    if (loaded.message().rfind(file.path() + ":", 0) != 0) std::abort();  // errors name the file
    return 0;
  }
  if (!markloop::ecu::validate_config(config)) return 0;
  const std::string printed = markloop::ecu::format_config(config);
  const markloop::fuzz::InputFile again_file(reinterpret_cast<const std::uint8_t*>(printed.data()),
                                             printed.size(), ".printed.conf");
  EcuConfig again;
  if (!markloop::ecu::load_config_file(again_file.path(), again)) std::abort();
  if (markloop::ecu::format_config(again) != printed) std::abort();
  return 0;
}
