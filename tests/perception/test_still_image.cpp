// The host tools' still-image reader: whole PNG and JPEG files decode to
// grey; truncated, foreign and missing ones are refused with the reason.
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <catch2/catch_test_macros.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "app/tools/common/still_image.hpp"
#include "tests/support/result_checks.hpp"

using markloop::io::check_still;
using markloop::io::declared_still_size;
using markloop::io::read_grey_still;
using markloop::io::StillCheck;
using markloop::test::error_of;
using markloop::test::loaded;

namespace {

const cv::Size kPictureSize(64, 48);

// A grey ramp with a bright bar: enough structure that JPEG keeps it.
cv::Mat test_picture() {
  cv::Mat image(kPictureSize, CV_8UC1);
  for (int r = 0; r < image.rows; ++r)
    for (int c = 0; c < image.cols; ++c)
      image.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(r > 20 && r < 28 ? 230 : 2 * c);
  return image;
}

std::vector<std::uint8_t> encoded(const char* extension) {
  std::vector<std::uint8_t> bytes;
  REQUIRE(cv::imencode(extension, test_picture(), bytes));
  return bytes;
}

std::string written(const std::string& name, const std::vector<std::uint8_t>& bytes) {
  const auto dir = std::filesystem::temp_directory_path() / "markloop-still-image-tests";
  std::filesystem::create_directories(dir);
  const std::string path = (dir / name).string();
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  return path;
}

std::vector<std::uint8_t> first(const std::vector<std::uint8_t>& bytes, std::size_t n) {
  return {bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(n)};
}

}  // namespace

TEST_CASE("Still image: whole PNG and JPEG files are complete and decode to grey") {
  for (const char* extension : {".png", ".jpg"}) {
    const auto bytes = encoded(extension);
    CHECK(check_still(bytes) == StillCheck::kComplete);
    const cv::Mat grey =
        loaded(read_grey_still(written(std::string("whole") + extension, bytes), kPictureSize));
    REQUIRE(grey.type() == CV_8UC1);
    CHECK(grey.size() == kPictureSize);
    CHECK(grey.at<std::uint8_t>(24, 10) > 200);  // the bar
  }
}

TEST_CASE("Still image: a PNG cut anywhere before its IEND chunk is truncated") {
  const auto bytes = encoded(".png");
  // IEND is the last 12 bytes; every cut from the signature on lacks it.
  for (std::size_t n = 8; n < bytes.size(); n += 7)
    CHECK(check_still(first(bytes, n)) == StillCheck::kTruncatedPng);
  CHECK(check_still(first(bytes, bytes.size() - 1)) == StillCheck::kTruncatedPng);
  CHECK(error_of(read_grey_still(written("cut.png", first(bytes, bytes.size() / 2)), kPictureSize)) ==
        "truncated PNG (it ends before its IEND chunk)");
}

TEST_CASE("Still image: a chunk length past the end of the file is not trusted") {
  auto bytes = encoded(".png");
  bytes[8] = 0x7f;  // the IHDR chunk's length now claims about 2 GB
  CHECK(check_still(bytes) == StillCheck::kTruncatedPng);
}

TEST_CASE("Still image: a JPEG without its end-of-image marker is truncated") {
  const auto bytes = encoded(".jpg");
  // libjpeg would decode these, the lost rows grey, with only a warning.
  for (std::size_t n : {bytes.size() - 2, bytes.size() * 3 / 4, bytes.size() / 2, std::size_t{3}})
    CHECK(check_still(first(bytes, n)) == StillCheck::kTruncatedJpeg);
  CHECK(error_of(read_grey_still(written("cut.jpg", first(bytes, bytes.size() - 2)), kPictureSize)) ==
        "truncated JPEG (no end-of-image marker after its image data)");

  // Bytes after the end-of-image marker (some cameras append data) are fine.
  auto padded = bytes;
  padded.insert(padded.end(), {0x00, 0x11, 0x22});
  CHECK(check_still(padded) == StillCheck::kComplete);
}

TEST_CASE("Still image: other files are refused with the reason") {
  const std::vector<std::uint8_t> text = {'h', 'e', 'l', 'l', 'o', '\n'};
  CHECK(check_still(text) == StillCheck::kUnknownFormat);
  CHECK(check_still({}) == StillCheck::kUnknownFormat);
  CHECK(error_of(read_grey_still(written("text.png", text), kPictureSize)) ==
        "cannot read as an image (PNG or JPEG)");
  CHECK(error_of(read_grey_still(written("empty.jpg", {}), kPictureSize)) ==
        "cannot read as an image (PNG or JPEG)");
  CHECK(error_of(read_grey_still("/nonexistent/still.png", kPictureSize)) ==
        "cannot open: No such file or directory");
}

TEST_CASE("Still image: the size a header declares is read before decoding") {
  CHECK(declared_still_size(encoded(".png")) == kPictureSize);
  CHECK(declared_still_size(encoded(".jpg")) == kPictureSize);
  const std::vector<std::uint8_t> text = {'h', 'e', 'l', 'l', 'o', '\n'};
  CHECK(declared_still_size(text).empty());

  // A JPEG whose frame header follows an application segment holding
  // another frame header (as an EXIF thumbnail's does): the segment is
  // skipped whole, so the image's own size is the one read.
  auto jpeg = encoded(".jpg");
  const std::vector<std::uint8_t> app1 = {0xff, 0xe1, 0x00, 0x0b, 0xff, 0xc0, 0x00,
                                          0x11, 0x08, 0x00, 0x10, 0x00, 0x20};
  jpeg.insert(jpeg.begin() + 2, app1.begin(), app1.end());
  CHECK(declared_still_size(jpeg) == kPictureSize);
  CHECK(loaded(read_grey_still(written("app1.jpg", jpeg), kPictureSize)).size() == kPictureSize);
}

TEST_CASE("Still image: a small file declaring a huge image is refused without decoding it") {
  // PNG: IHDR's width and height (bytes 16..23) set to 60000 x 60000, a
  // 3.6 GB grey image; its CRC now fails, so decoding would say "corrupt",
  // not the size.
  auto png = encoded(".png");
  for (const std::size_t at : {16u, 20u}) {
    png[at] = 0;
    png[at + 1] = 0;
    png[at + 2] = 0xea;
    png[at + 3] = 0x60;
  }
  CHECK(declared_still_size(png) == cv::Size(60000, 60000));
  CHECK(error_of(read_grey_still(written("huge.png", png), kPictureSize)) ==
        "image is 60000x60000, the camera's 64x48");

  // JPEG: the frame header's height and width (after its precision byte).
  auto jpeg = encoded(".jpg");
  std::size_t frame = 2;
  while (!(jpeg[frame] == 0xff && jpeg[frame + 1] == 0xc0))
    frame += 2 + (jpeg[frame + 2] << 8 | jpeg[frame + 3]);
  jpeg[frame + 5] = 0xff;  // height 65535
  jpeg[frame + 6] = 0xff;
  CHECK(declared_still_size(jpeg) == cv::Size(64, 65535));
  CHECK(error_of(read_grey_still(written("huge.jpg", jpeg), kPictureSize)) ==
        "image is 64x65535, the camera's 64x48");

  // The right format at another size is refused the same way.
  CHECK(error_of(read_grey_still(written("whole.png", encoded(".png")), {1280, 512})) ==
        "image is 64x48, the camera's 1280x512");
}

TEST_CASE("Still image: a header without a size is not decoded") {
  // IHDR's length changed: the first chunk is no longer a valid IHDR.
  auto png = encoded(".png");
  png[11] = 12;
  CHECK(declared_still_size(png).empty());
  // A JPEG whose first segment's length runs past the end of the file.
  auto jpeg = encoded(".jpg");
  jpeg[4] = 0xff;
  jpeg[5] = 0xff;
  CHECK(declared_still_size(jpeg).empty());
  CHECK(error_of(read_grey_still(written("nosize.jpg", jpeg), kPictureSize)) ==
        "corrupt PNG or JPEG (no image size in its header)");
}
