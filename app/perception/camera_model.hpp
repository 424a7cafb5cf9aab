// A camera looking at a flat road: maps between image pixels and points on
// the ground in the vehicle frame (x ahead, y left, metres, z up, origin on
// the ground under the vehicle reference point).
//
// Two calibrations are supported, both read from OpenCV FileStorage YAML:
//  - pinhole: the fields OpenCV's calibration tools write (image_width,
//    image_height, camera_matrix, distortion_coefficients as k1 k2 p1 p2
//    [k3]) plus the mounting: mount_x, mount_y, mount_height (metres) and
//    mount_pitch_deg (positive looking down), mount_roll_deg, mount_yaw_deg
//    (positive to the left);
//  - homography: image_width, image_height and ground_homography, a 3x3
//    matrix taking [u v 1] (pixels) to [x y 1] (metres, vehicle frame), for
//    cameras calibrated against the road directly.
#pragma once

#include <array>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "app/common/result.hpp"

namespace markloop::perception {

struct PinholeIntrinsics {
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;
  std::array<double, 5> distortion{};  // OpenCV order: k1 k2 p1 p2 k3
};

struct CameraMounting {
  double x_m = 0.0;  // camera position in the vehicle frame
  double y_m = 0.0;
  double height_m = 1.5;
  double pitch_rad = 0.0;  // positive: looking down
  double roll_rad = 0.0;
  double yaw_rad = 0.0;  // positive: looking left
};

class CameraModel {
 public:
  static CameraModel pinhole(int width, int height, const PinholeIntrinsics& intrinsics,
                             const CameraMounting& mounting);
  static CameraModel homography(int width, int height, const Eigen::Matrix3d& image_to_ground);

  int width() const { return width_; }
  int height() const { return height_; }
  bool is_pinhole() const { return is_pinhole_; }
  const PinholeIntrinsics& intrinsics() const { return intrinsics_; }
  const CameraMounting& mounting() const { return mounting_; }
  const Eigen::Matrix3d& image_to_ground_homography() const { return image_to_ground_; }

  // Pixel (distorted, as the camera sees it) of a ground point; false when
  // the point is behind or too close to the camera's image plane. The pixel
  // may lie outside the image.
  bool ground_to_image(const Eigen::Vector2d& ground, Eigen::Vector2d& pixel) const;
  // Ground point seen at a pixel; false when the pixel's ray does not meet
  // the ground in front of the camera (at or above the horizon).
  bool image_to_ground(const Eigen::Vector2d& pixel, Eigen::Vector2d& ground) const;

 private:
  int width_ = 0, height_ = 0;
  bool is_pinhole_ = true;
  PinholeIntrinsics intrinsics_;
  CameraMounting mounting_;
  Eigen::Matrix3d vehicle_to_camera_ = Eigen::Matrix3d::Identity();  // rotation
  Eigen::Vector3d camera_position_ = Eigen::Vector3d::Zero();        // in the vehicle frame
  Eigen::Matrix3d image_to_ground_ = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d ground_to_image_ = Eigen::Matrix3d::Identity();
};

// Reads a calibration file. An error says "PATH: what is wrong".
Result<CameraModel> load_camera_model(const std::string& path);
// Writes a calibration file that load_camera_model() reads back.
Status save_camera_model(const CameraModel& model, const std::string& path);

// The simulator's default camera (and the ECU's when no calibration is
// given): 1280x512 grey, 71 degrees wide, 1.5 m high, 12 degrees down.
CameraModel default_camera_model();

}  // namespace markloop::perception
