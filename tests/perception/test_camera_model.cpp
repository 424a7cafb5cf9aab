#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>

#include <catch2/catch_approx.hpp>
#include <catch2/catch_test_macros.hpp>

#include "app/perception/camera_model.hpp"
#include "app/perception/marking_detector.hpp"
#include "app/perception/storage_file.hpp"

using namespace markloop::perception;
using Catch::Approx;

namespace {

std::filesystem::path scratch(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / "markloop-camera-tests";
  std::filesystem::create_directories(dir);
  return dir / name;
}

void write_file(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path) << text;
}

// Loads the calibration at `path`: true when it loads, else false with its
// message in `error`.
bool loads_camera(const std::string& path, std::string& error) {
  const markloop::Result<CameraModel> camera = load_camera_model(path);
  error = camera ? std::string() : camera.message();
  return camera.ok();
}

// As loads_camera(), for the detector's keys.
bool loads_detector(const std::string& path, std::string& error) {
  const markloop::Result<DetectorConfig> config = load_detector_config(path);
  error = config ? std::string() : config.message();
  return config.ok();
}

}  // namespace

TEST_CASE("Pinhole camera: ground to image and back is the identity") {
  const CameraModel camera = default_camera_model();
  for (double x = 3.0; x <= 40.0; x += 1.7) {
    for (double y = -6.0; y <= 6.0; y += 0.9) {
      Eigen::Vector2d pixel, ground;
      REQUIRE(camera.ground_to_image({x, y}, pixel));
      REQUIRE(camera.image_to_ground(pixel, ground));
      CHECK(ground.x() == Approx(x).margin(1e-6 * x * x));
      CHECK(ground.y() == Approx(y).margin(1e-6 * x * x));
    }
  }
}

TEST_CASE("Pinhole camera: geometry follows the mounting") {
  CameraMounting mount;
  mount.height_m = 1.2;
  mount.pitch_rad = 10.0 * std::numbers::pi / 180.0;
  PinholeIntrinsics k{800.0, 800.0, 400.0, 300.0, {}};
  const CameraModel camera = CameraModel::pinhole(800, 600, k, mount);
  // The optical axis meets the ground at height / tan(pitch), straight ahead.
  Eigen::Vector2d ground;
  REQUIRE(camera.image_to_ground({400.0, 300.0}, ground));
  CHECK(ground.x() == Approx(1.2 / std::tan(mount.pitch_rad)));
  CHECK(ground.y() == Approx(0.0).margin(1e-9));
  // Points to the left of the car appear left in the image.
  Eigen::Vector2d pixel;
  REQUIRE(camera.ground_to_image({10.0, 2.0}, pixel));
  CHECK(pixel.x() < 400.0);
  // Above the horizon there is no ground; behind the camera no pixel.
  CHECK_FALSE(camera.image_to_ground({400.0, 0.0}, ground));
  CHECK_FALSE(camera.ground_to_image({-5.0, 0.0}, pixel));
}

TEST_CASE("Camera files round-trip through OpenCV YAML") {
  const auto path = scratch("default.yaml").string();
  REQUIRE(save_camera_model(default_camera_model(), path));
  const auto loaded = load_camera_model(path);
  REQUIRE(loaded);
  CHECK(loaded->width() == 1280);
  CHECK(loaded->height() == 512);
  Eigen::Vector2d a, b;
  REQUIRE(default_camera_model().ground_to_image({12.0, 1.5}, a));
  REQUIRE(loaded->ground_to_image({12.0, 1.5}, b));
  CHECK((a - b).norm() < 1e-6);
}

TEST_CASE("Homography cameras map through the matrix") {
  const auto path = scratch("homography.yaml").string();
  write_file(path,
             "%YAML:1.0\n---\nimage_width: 800\nimage_height: 600\n"
             "ground_homography: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n"
             "  data: [ 0.0, -0.1, 60.0, -0.05, 0.0, 20.0, 0.0, 0.0, 1.0 ]\n");
  const auto camera = load_camera_model(path);
  REQUIRE(camera);
  CHECK_FALSE(camera->is_pinhole());
  Eigen::Vector2d ground, pixel;
  REQUIRE(camera->image_to_ground({400.0, 500.0}, ground));
  CHECK(ground.x() == Approx(10.0));
  CHECK(ground.y() == Approx(0.0).margin(1e-9));
  REQUIRE(camera->ground_to_image(ground, pixel));
  CHECK(pixel.x() == Approx(400.0));
  CHECK(pixel.y() == Approx(500.0));
}

TEST_CASE("Bad calibration files are refused with the path and the reason") {
  std::string error;
  CHECK_FALSE(loads_camera(scratch("missing.yaml").string(), error));
  CHECK(error.find("missing.yaml") != std::string::npos);

  const auto garbage = scratch("garbage.yaml");
  write_file(garbage, "%YAML:1.0\n---\nimage_width: [ unbalanced\n");
  CHECK_FALSE(loads_camera(garbage.string(), error));
  CHECK(error.find("garbage.yaml") != std::string::npos);

  // A pinhole camera's size and intrinsics, without its mounting.
  const std::string intrinsics_only =
      "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n"
      "camera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n"
      "  data: [ 500., 0., 320., 0., 500., 240., 0., 0., 1. ]\n";
  const auto no_mount = scratch("no_mount.yaml");
  write_file(no_mount, intrinsics_only);
  CHECK_FALSE(loads_camera(no_mount.string(), error));
  CHECK(error.find("mount_height") != std::string::npos);

  const auto bad_size = scratch("bad_size.yaml");
  write_file(bad_size, "%YAML:1.0\n---\nimage_width: -3\nimage_height: 480\n");
  CHECK_FALSE(loads_camera(bad_size.string(), error));
  CHECK(error.find("out of range") != std::string::npos);

  // Found by the fuzz target: OpenCV sizes a matrix by its rows and cols
  // before reading its data, so a damaged shape asked for gigabytes.
  const auto huge = scratch("huge_matrix.yaml");
  write_file(huge,
             "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n"
             "camera_matrix: !!opencv-matrix\n  rows: 100000\n  cols: 100000\n  dt: d\n"
             "  data: [ 500., 0., 320., 0., 500., 240., 0., 0., 1. ]\n");
  CHECK_FALSE(loads_camera(huge.string(), error));
  CHECK(error.find("camera_matrix (3x3)") != std::string::npos);
  const auto long_distortion = scratch("long_distortion.yaml");
  write_file(long_distortion,
             intrinsics_only +
                 "distortion_coefficients: !!opencv-matrix\n  rows: 1\n  cols: 1000000000\n  dt: d\n"
                 "  data: [ 0., 0., 0., 0. ]\n");
  CHECK_FALSE(loads_camera(long_distortion.string(), error));
  CHECK(error.find("distortion_coefficients must hold 4 or 5") != std::string::npos);

  // Found by the fuzz target: OpenCV 4.6's YAML reader never returns on a
  // line beginning with "----" followed by more lines. Refused before it.
  const auto dashes = scratch("dashes.yaml");
  write_file(dashes, "%YAML:1.0\n----ima0\n----imagewt\ngewt\n");
  CHECK_FALSE(loads_camera(dashes.string(), error));
  CHECK(error.find("dashes.yaml:2: a line beginning with \"----\"") != std::string::npos);
  CHECK_FALSE(loads_detector(dashes.string(), error));
  CHECK(error.find("dashes.yaml:2:") != std::string::npos);

  const auto too_large = scratch("too_large.yaml");
  write_file(too_large, "%YAML:1.0\n---\n" + std::string(kMaxStorageFileBytes, '#') + "\n");
  CHECK_FALSE(loads_camera(too_large.string(), error));
  CHECK(error.find("too_large.yaml: larger than 1 MiB") != std::string::npos);
}

TEST_CASE("Calibrations that would crash the parser or describe no usable camera are refused") {
  std::string error;
  const std::string header = "%YAML:1.0\n---\nimage_width: 1280\nimage_height: 512\n";
  // OpenCV's parsers recurse once per level: 50,000 levels overflow the stack.
  const auto deep = scratch("deep.yaml");
  write_file(deep, header + "camera_matrix: " + std::string(50000, '[') + std::string(50000, ']') + "\n");
  CHECK_FALSE(loads_camera(deep.string(), error));
  CHECK(error.find("deep.yaml:5: nested more than 32 levels deep") != std::string::npos);
  const auto deep_block = scratch("deep_block.yaml");
  std::string dashes;
  for (int i = 0; i < 50000; ++i) dashes += "- ";
  write_file(deep_block, header + "camera_matrix:\n  " + dashes + "1\n");
  CHECK_FALSE(loads_camera(deep_block.string(), error));
  CHECK(error.find("deep_block.yaml:6: nested more than 32 levels deep") != std::string::npos);
  const auto deep_xml = scratch("deep.xml");
  std::string elements;
  for (int i = 0; i < 50000; ++i) elements += "<a>";
  write_file(deep_xml, "<?xml version=\"1.0\"?>\n<opencv_storage>\n" + elements + "\n");
  CHECK_FALSE(loads_camera(deep_xml.string(), error));
  CHECK(error.find("deep.xml:3: nested more than 32 levels deep") != std::string::npos);

  const std::string pinhole = header +
                              "camera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n"
                              "  data: [ 900., 0., 639.5, 0., 900., 255.5, 0., 0., 1. ]\n"
                              "mount_height: 1.5\n";
  const auto nan = scratch("nan_distortion.yaml");
  write_file(nan, pinhole +
                      "mount_pitch_deg: 12\ndistortion_coefficients: !!opencv-matrix\n  rows: 1\n"
                      "  cols: 5\n  dt: d\n  data: [ .nan, 0., 0., 0., 0. ]\n");
  CHECK_FALSE(loads_camera(nan.string(), error));
  CHECK(error.find("nan_distortion.yaml: distortion_coefficients must be finite") != std::string::npos);
  const auto inf = scratch("inf_distortion.yaml");
  write_file(inf, pinhole +
                      "mount_pitch_deg: 12\ndistortion_coefficients: !!opencv-matrix\n  rows: 1\n"
                      "  cols: 4\n  dt: d\n  data: [ 0., -.inf, 0., 0. ]\n");
  CHECK_FALSE(loads_camera(inf.string(), error));
  CHECK(error.find("inf_distortion.yaml: distortion_coefficients must be finite") != std::string::npos);

  // Turned to look sideways: the road ahead is out of the picture.
  const auto sideways = scratch("sideways.yaml");
  write_file(sideways, pinhole + "mount_pitch_deg: 12\nmount_yaw_deg: 90\n");
  CHECK_FALSE(loads_camera(sideways.string(), error));
  CHECK(error.find("sideways.yaml: the camera sees no road") != std::string::npos);
  const auto telescope = scratch("telescope.yaml");
  write_file(telescope, header +
                            "camera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n"
                            "  data: [ 1e308, 0., 639.5, 0., 900., 255.5, 0., 0., 1. ]\n"
                            "mount_height: 1.5\nmount_pitch_deg: 12\n");
  CHECK_FALSE(loads_camera(telescope.string(), error));
  CHECK(error.find("telescope.yaml: camera_matrix needs focal lengths of 0 to 100000 pixels") !=
        std::string::npos);
  const auto level = scratch("level.yaml");
  write_file(level, pinhole + "mount_pitch_deg: 12\n");
  CHECK(loads_camera(level.string(), error));
}

TEST_CASE("The shipped default calibration is the built-in default") {
  const auto shipped = load_camera_model(MARKLOOP_SOURCE_DIR "/app/cameras/sim.yaml");
  INFO((shipped ? std::string() : shipped.message()));
  REQUIRE(shipped);
  Eigen::Vector2d a, b;
  for (const Eigen::Vector2d& g : {Eigen::Vector2d(5, 0), Eigen::Vector2d(20, -4), Eigen::Vector2d(9, 3)}) {
    REQUIRE(default_camera_model().ground_to_image(g, a));
    REQUIRE(shipped->ground_to_image(g, b));
    CHECK((a - b).norm() < 1e-3);
  }
}
