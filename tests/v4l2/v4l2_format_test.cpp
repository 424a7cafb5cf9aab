// Pure helpers of the V4L2 drivers: fourcc codes, error category, sequence
// gaps, luma extraction and filling.
#include <catch2/catch_test_macros.hpp>

#include <linux/videodev2.h>

#include <cstring>
#include <string>
#include <vector>

#include "drivers/v4l2/v4l2_format.hpp"

using namespace markloop::v4l2;

TEST_CASE("fourcc codes are the kernel's") {
  STATIC_CHECK(make_fourcc('G', 'R', 'E', 'Y') == V4L2_PIX_FMT_GREY);
  STATIC_CHECK(make_fourcc('Y', 'U', 'Y', 'V') == V4L2_PIX_FMT_YUYV);
  CHECK(to_fourcc(PixelFormat::Grey) == V4L2_PIX_FMT_GREY);
  CHECK(to_fourcc(PixelFormat::Yuyv) == V4L2_PIX_FMT_YUYV);
  CHECK(from_fourcc(V4L2_PIX_FMT_GREY) == PixelFormat::Grey);
  CHECK(from_fourcc(V4L2_PIX_FMT_YUYV) == PixelFormat::Yuyv);
  CHECK_FALSE(from_fourcc(V4L2_PIX_FMT_MJPEG).has_value());
  CHECK_FALSE(from_fourcc(0).has_value());
  CHECK(bytes_per_pixel(PixelFormat::Grey) == 1);
  CHECK(bytes_per_pixel(PixelFormat::Yuyv) == 2);
  CHECK(std::string(to_string(PixelFormat::Yuyv)) == "YUYV");
}

TEST_CASE("fourcc strings are printable and terminated") {
  CHECK(std::string(fourcc_string(V4L2_PIX_FMT_NV12).data()) == "NV12");
  CHECK(std::string(fourcc_string(V4L2_PIX_FMT_Y16_BE).data()) == "Y16?");
  CHECK(std::string(fourcc_string(0x01020304).data()) == "????");
  CHECK(fourcc_string(0)[4] == '\0');
}

TEST_CASE("driver errors have their own category and messages") {
  const std::error_code ec = V4l2Error::TooFewBuffers;
  CHECK(ec.category() == v4l2_category());
  CHECK(std::string(ec.category().name()) == "v4l2");
  CHECK(ec.message() == "driver granted fewer buffers than requested");
  CHECK(ec != std::errc::invalid_argument);
  CHECK(std::error_code(V4l2Error::FormatRefused).message() !=
        std::error_code(V4l2Error::SizeRefused).message());
}

TEST_CASE("sequence gaps count missed frames") {
  SequenceTracker t;
  CHECK_FALSE(t.has_last());
  auto s = t.update(5);  // the first frame: nothing to compare with
  CHECK(s.missed == 0);
  CHECK_FALSE(s.restarted);
  CHECK(t.update(6).missed == 0);
  CHECK(t.update(9).missed == 2);
  CHECK(t.update(10).missed == 0);
  CHECK(t.last() == 10);
}

TEST_CASE("sequence numbers wrap at 2^32 without a false gap") {
  SequenceTracker t;
  t.update(0xFFFF'FFFEU);
  CHECK(t.update(0xFFFF'FFFFU).missed == 0);
  CHECK(t.update(0).missed == 0);
  CHECK(t.update(3).missed == 2);
}

TEST_CASE("a backwards or repeated sequence is a restart, not a loss") {
  SequenceTracker t;
  t.update(100);
  auto s = t.update(2);
  CHECK(s.restarted);
  CHECK(s.missed == 0);
  s = t.update(2);
  CHECK(s.restarted);
  CHECK(t.update(3).missed == 0);
  t.reset();
  CHECK_FALSE(t.has_last());
  s = t.update(50);
  CHECK_FALSE(s.restarted);
  CHECK(s.missed == 0);
}

TEST_CASE("luma of a GREY image with padded rows") {
  const std::uint32_t w = 3, h = 2, stride = 4;
  const std::vector<std::uint8_t> image = {1, 2, 3, 99, 4, 5, 6, 99};
  std::vector<std::uint8_t> out(w * h);
  REQUIRE(extract_luma(PixelFormat::Grey, image, w, h, stride, out));
  CHECK(out == std::vector<std::uint8_t>{1, 2, 3, 4, 5, 6});
  // The last row needs no padding.
  const std::vector<std::uint8_t> tight(image.begin(), image.begin() + 7);
  CHECK(extract_luma(PixelFormat::Grey, tight, w, h, stride, out));
}

TEST_CASE("luma of a YUYV image is every other byte") {
  const std::uint32_t w = 2, h = 2, stride = 4;
  const std::vector<std::uint8_t> image = {10, 128, 20, 129, 30, 130, 40, 131};
  std::vector<std::uint8_t> out(w * h);
  REQUIRE(extract_luma(PixelFormat::Yuyv, image, w, h, stride, out));
  CHECK(out == std::vector<std::uint8_t>{10, 20, 30, 40});
}

TEST_CASE("luma extraction refuses wrong sizes") {
  std::vector<std::uint8_t> image(16), out(4);
  CHECK_FALSE(extract_luma(PixelFormat::Grey, image, 2, 2, 1, out));                      // stride < width
  CHECK_FALSE(extract_luma(PixelFormat::Yuyv, image, 2, 2, 3, out));                      // stride < 2*width
  CHECK_FALSE(extract_luma(PixelFormat::Grey, std::span(image).first(3), 2, 2, 2, out));  // short
  std::vector<std::uint8_t> small(3);
  CHECK_FALSE(extract_luma(PixelFormat::Grey, image, 2, 2, 2, small));                    // output size
  CHECK_FALSE(extract_luma(PixelFormat::Yuyv, image, 3, 1, 6, std::span(out).first(3)));  // odd YUYV width
  CHECK_FALSE(extract_luma(PixelFormat::Grey, image, 0, 2, 2, std::span(out).first(0)));
}

TEST_CASE("filling from luma round-trips through extraction") {
  const std::uint32_t w = 4, h = 3;
  std::vector<std::uint8_t> luma(w * h);
  for (std::size_t i = 0; i < luma.size(); ++i) luma[i] = static_cast<std::uint8_t>(i * 17 + 3);
  for (PixelFormat f : {PixelFormat::Grey, PixelFormat::Yuyv}) {
    const std::uint32_t stride = w * bytes_per_pixel(f) + 2;
    std::vector<std::uint8_t> image(stride * h, 0xEE);
    REQUIRE(fill_from_luma(f, luma, w, h, stride, image));
    std::vector<std::uint8_t> back(w * h);
    REQUIRE(extract_luma(f, image, w, h, stride, back));
    CHECK(back == luma);
    if (f == PixelFormat::Yuyv) CHECK(image[1] == 128);
    CHECK(image[stride - 1] == 0xEE);  // padding untouched
  }
  std::vector<std::uint8_t> tiny(5);
  CHECK_FALSE(fill_from_luma(PixelFormat::Grey, luma, w, h, w, tiny));
}
