// Y4M recordings (the ECU's file mode, markloop-eval): any bytes give frames,
// a clean end or an error, never a crash or a read past the frame buffer.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "app/io/y4m.hpp"
#include "tests/fuzz/fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const markloop::fuzz::InputFile file(data, size, ".y4m");
  markloop::io::Y4mReader reader;
  if (!reader.open(file.path())) return 0;
  // The ECU opens with its camera's size; a header may declare any size, so
  // the harness caps what it allocates (its own limit, not the reader's).
  const std::size_t luma = reader.format().luma_bytes();
  if (luma == 0 || luma > (std::size_t{1} << 24)) return 0;
  std::vector<std::uint8_t> frame(luma);
  for (int i = 0; i < 64; ++i)
    if (reader.read_frame(frame) != markloop::io::Y4mRead::kFrame) break;
  return 0;
}
