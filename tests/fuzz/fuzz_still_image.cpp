// Still images (markloop-detect): any bytes decode to a grey frame of the
// camera's size or are refused with the reason, before any large
// allocation (the header's size is checked first).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include <opencv2/core.hpp>

#include "app/tools/common/still_image.hpp"
#include "tests/fuzz/fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const cv::Size camera(64, 48);
  for (const char* suffix : {".png", ".jpg"}) {
    const markloop::fuzz::InputFile file(data, size, suffix);
    const markloop::Result<cv::Mat> grey = markloop::io::read_grey_still(file.path(), camera);
    if (!grey) {
      if (grey.message().empty()) std::abort();  // refused, and why
    } else if (grey->size() != camera || grey->type() != CV_8UC1) {
      std::abort();
    }
  }
  return 0;
}
