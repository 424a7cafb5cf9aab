// candump -L log lines (the ECU's file mode, markloop-eval): every line is
// parsed or refused with a column; a parsed frame prints back as a line that
// parses to the same frame.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "drivers/can/candump_log.hpp"

using namespace markloop::can;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string_view text(reinterpret_cast<const char*>(data), size);
  while (!text.empty()) {
    const std::size_t end = text.find('\n');
    const std::string_view line = text.substr(0, end);
    text = end == std::string_view::npos ? std::string_view{} : text.substr(end + 1);

    CandumpRecord record;
    CandumpLineError error;
    if (!parse_candump_line(line, record, error)) {
      if (error.what == nullptr || error.column == 0 || error.column > line.size() + 1) std::abort();
      continue;
    }
    char printed[kCandumpMaxLine + 2];
    const std::size_t n = format_candump_line(record.frame, record.interface_name(), printed, sizeof printed);
    if (n == 0) std::abort();  // a frame the parser accepted must print
    CandumpRecord again;
    if (!parse_candump_line(std::string_view(printed, n - 1), again, error)) std::abort();
    if (!same_content(again.frame, record.frame) || again.frame.timestamp_ns != record.frame.timestamp_ns ||
        again.interface_name() != record.interface_name())
      std::abort();
  }
  return 0;
}
