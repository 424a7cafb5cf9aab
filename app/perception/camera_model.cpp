#include "app/perception/camera_model.hpp"

#include <cmath>
#include <exception>
#include <numbers>

#include <Eigen/Geometry>
#include <opencv2/core/persistence.hpp>

#include "app/common/units.hpp"
#include "app/perception/storage_file.hpp"

namespace markloop::perception {
namespace {

// Points closer than this to the camera plane are not projected: their
// pixels would be meaningless (and distortion polynomials diverge).
constexpr double kMinDepth = 0.05;
constexpr int kUndistortIterations = 20;

Eigen::Vector2d distort(const PinholeIntrinsics& k, double xn, double yn) {
  const auto& d = k.distortion;
  const double r2 = xn * xn + yn * yn;
  const double radial = 1.0 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
  const double xd = xn * radial + 2.0 * d[2] * xn * yn + d[3] * (r2 + 2.0 * xn * xn);
  const double yd = yn * radial + d[2] * (r2 + 2.0 * yn * yn) + 2.0 * d[3] * xn * yn;
  return {k.fx * xd + k.cx, k.fy * yd + k.cy};
}

// Fixed-point inversion of distort(), as cv::undistortPoints does.
Eigen::Vector2d undistort(const PinholeIntrinsics& k, const Eigen::Vector2d& pixel) {
  const auto& d = k.distortion;
  const double xd = (pixel.x() - k.cx) / k.fx;
  const double yd = (pixel.y() - k.cy) / k.fy;
  double xn = xd, yn = yd;
  for (int i = 0; i < kUndistortIterations; ++i) {
    const double r2 = xn * xn + yn * yn;
    const double radial = 1.0 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
    const double dx = 2.0 * d[2] * xn * yn + d[3] * (r2 + 2.0 * xn * xn);
    const double dy = d[2] * (r2 + 2.0 * yn * yn) + 2.0 * d[3] * xn * yn;
    xn = (xd - dx) / radial;
    yn = (yd - dy) / radial;
  }
  return {xn, yn};
}

}  // namespace

CameraModel CameraModel::pinhole(int width, int height, const PinholeIntrinsics& intrinsics,
                                 const CameraMounting& mounting) {
  CameraModel model;
  model.width_ = width;
  model.height_ = height;
  model.is_pinhole_ = true;
  model.intrinsics_ = intrinsics;
  model.mounting_ = mounting;
  // Camera orientation in the vehicle frame: yaw about z (up), then pitch
  // about y (left; positive tips the optical axis down), then roll about x.
  const Eigen::Matrix3d mount = (Eigen::AngleAxisd(mounting.yaw_rad, Eigen::Vector3d::UnitZ()) *
                                 Eigen::AngleAxisd(mounting.pitch_rad, Eigen::Vector3d::UnitY()) *
                                 Eigen::AngleAxisd(mounting.roll_rad, Eigen::Vector3d::UnitX()))
                                    .toRotationMatrix();
  // Rows: the camera's x (right), y (down) and z (optical axis) expressed
  // in the vehicle frame, for a camera that looks straight ahead.
  Eigen::Matrix3d level;
  level << 0, -1, 0,  //
      0, 0, -1,       //
      1, 0, 0;
  model.vehicle_to_camera_ = level * mount.transpose();
  model.camera_position_ = {mounting.x_m, mounting.y_m, mounting.height_m};
  return model;
}

CameraModel CameraModel::homography(int width, int height, const Eigen::Matrix3d& image_to_ground) {
  CameraModel model;
  model.width_ = width;
  model.height_ = height;
  model.is_pinhole_ = false;
  model.image_to_ground_ = image_to_ground;
  model.ground_to_image_ = image_to_ground.inverse();
  return model;
}

bool CameraModel::ground_to_image(const Eigen::Vector2d& ground, Eigen::Vector2d& pixel) const {
  if (!is_pinhole_) {
    const Eigen::Vector3d p = ground_to_image_ * ground.homogeneous();
    if (!(p.z() > 1e-12)) return false;
    pixel = p.hnormalized();
    return true;
  }
  const Eigen::Vector3d c =
      vehicle_to_camera_ * (Eigen::Vector3d(ground.x(), ground.y(), 0.0) - camera_position_);
  if (!(c.z() > kMinDepth)) return false;
  pixel = distort(intrinsics_, c.x() / c.z(), c.y() / c.z());
  return true;
}

bool CameraModel::image_to_ground(const Eigen::Vector2d& pixel, Eigen::Vector2d& ground) const {
  if (!is_pinhole_) {
    const Eigen::Vector3d g = image_to_ground_ * pixel.homogeneous();
    // The homography's scale sign tells the ground half-plane in front of
    // the camera from the mirrored one behind the horizon.
    const Eigen::Vector3d centre = image_to_ground_ * Eigen::Vector3d(width_ / 2.0, height_ - 1.0, 1.0);
    if (!(g.z() * centre.z() > 0.0)) return false;
    ground = g.hnormalized();
    return true;
  }
  const Eigen::Vector2d n = undistort(intrinsics_, pixel);
  const Eigen::Vector3d ray = vehicle_to_camera_.transpose() * Eigen::Vector3d(n.x(), n.y(), 1.0);
  if (!(ray.z() < -1e-9)) return false;
  const double s = -camera_position_.z() / ray.z();
  ground = {camera_position_.x() + s * ray.x(), camera_position_.y() + s * ray.y()};
  return true;
}

namespace {

// An !!opencv-matrix of at most `max_values` values. OpenCV allocates a
// matrix by its "rows" and "cols" before it reads "data": a damaged file could
// ask for gigabytes (the fuzz target found "rows:=3" asking for 48 GB), so
// the shape is checked first.
bool read_small_matrix(const cv::FileNode& node, int max_values, cv::Mat& m) {
  if (!node.isMap()) return false;
  const cv::FileNode rows = node["rows"], cols = node["cols"];
  if (!rows.isInt() || !cols.isInt()) return false;
  const int r = static_cast<int>(rows), c = static_cast<int>(cols);
  if (r < 1 || c < 1 || r > max_values || c > max_values || r * c > max_values) return false;
  node >> m;
  // Whole-number types would round the principal point and the coefficients.
  return !m.empty() && (m.depth() == CV_64F || m.depth() == CV_32F);
}

bool read_matrix(const cv::FileNode& node, int rows, int cols, double* out) {
  cv::Mat m;
  if (!read_small_matrix(node, rows * cols, m)) return false;
  m.convertTo(m, CV_64F);
  if (m.total() != static_cast<std::size_t>(rows * cols)) return false;
  for (int i = 0; i < rows * cols; ++i) out[i] = m.at<double>(i);
  return true;
}

bool read_number(const cv::FileNode& node, double& out) {
  if (node.empty() || (!node.isReal() && !node.isInt())) return false;
  out = static_cast<double>(node);
  return std::isfinite(out);
}

// Larger coefficients describe no lens: the distortion polynomial would fold
// the image over itself.
constexpr double kMaxDistortion = 100.0;
// A longer focal length would be a telescope (a 1 mm pixel at 100 km).
constexpr double kMaxFocalPixels = 100000.0;

// True when some of the road where markings are detected lies in the image.
bool sees_road(const CameraModel& model) {
  for (double ahead = 5.0; ahead <= 20.0; ahead += 1.0) {
    for (double side = -3.0; side <= 3.0; side += 0.5) {
      Eigen::Vector2d pixel;
      if (model.ground_to_image(Eigen::Vector2d(ahead, side), pixel) && pixel.allFinite() && pixel.x() >= 0 &&
          pixel.y() >= 0 && pixel.x() < model.width() && pixel.y() < model.height())
        return true;
    }
  }
  return false;
}

// The image's size, in whole pixels.
struct ImageSize {
  int width, height;
};

Result<ImageSize> read_image_size(const cv::FileStorage& fs) {
  double width = 0, height = 0;
  if (!read_number(fs["image_width"], width) || !read_number(fs["image_height"], height))
    return error("image_width and image_height are required");
  if (width < 16 || height < 16 || width > 8192 || height > 8192 || width != std::floor(width) ||
      height != std::floor(height))
    return error("image size " + std::to_string(width) + "x" + std::to_string(height) +
                 " out of range (16..8192 whole pixels)");
  return ImageSize{static_cast<int>(width), static_cast<int>(height)};
}

// A camera calibrated against the road directly (ground_homography).
Result<CameraModel> read_homography_camera(const cv::FileStorage& fs, ImageSize size) {
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> H;
  if (!read_matrix(fs["ground_homography"], 3, 3, H.data()))
    return error("ground_homography must be a 3x3 matrix");
  if (!H.allFinite() || std::abs(H.determinant()) < 1e-15)
    return error("ground_homography is singular or not finite");
  CameraModel model = CameraModel::homography(size.width, size.height, H);
  if (!sees_road(model))
    return error(
        "the camera sees no road: no ground point 5 to 20 m ahead of the car, within 3 m of "
        "its axis, falls inside the image (check ground_homography)");
  return model;
}

Status read_distortion(const cv::FileStorage& fs, PinholeIntrinsics& k) {
  if (fs["distortion_coefficients"].empty()) return {};
  cv::Mat d;
  if (read_small_matrix(fs["distortion_coefficients"], 5, d)) d.convertTo(d, CV_64F);
  if (d.total() != 4 && d.total() != 5)
    return error("distortion_coefficients must hold 4 or 5 values (k1 k2 p1 p2 [k3])");
  for (std::size_t i = 0; i < d.total(); ++i) k.distortion[i] = d.at<double>(static_cast<int>(i));
  for (const double v : k.distortion)
    if (!std::isfinite(v) || std::abs(v) > kMaxDistortion)
      return error("distortion_coefficients must be finite numbers within +-" +
                   std::to_string(int(kMaxDistortion)));
  return {};
}

Result<PinholeIntrinsics> read_intrinsics(const cv::FileStorage& fs, ImageSize size) {
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> K;
  if (!read_matrix(fs["camera_matrix"], 3, 3, K.data()))
    return error("camera_matrix (3x3) or ground_homography is required");
  PinholeIntrinsics k;
  k.fx = K(0, 0);
  k.fy = K(1, 1);
  k.cx = K(0, 2);
  k.cy = K(1, 2);
  if (!(k.fx > 0 && k.fy > 0) || !K.allFinite() || k.fx > kMaxFocalPixels || k.fy > kMaxFocalPixels)
    return error("camera_matrix needs focal lengths of 0 to " + std::to_string(int(kMaxFocalPixels)) +
                 " pixels");
  if (k.cx < 0 || k.cy < 0 || k.cx >= size.width || k.cy >= size.height)
    return error("camera_matrix's principal point lies outside the image");
  if (Status distortion = read_distortion(fs, k); !distortion) return distortion.error();
  return k;
}

Result<CameraMounting> read_mounting(const cv::FileStorage& fs) {
  CameraMounting m;
  double pitch = 0, roll = 0, yaw = 0;
  if (!read_number(fs["mount_height"], m.height_m) || !(m.height_m > 0.1 && m.height_m < 10))
    return error("mount_height (metres above the road, 0.1..10) is required");
  if (!read_number(fs["mount_pitch_deg"], pitch) || !(pitch > 0.5 && pitch < 89.5))
    return error("mount_pitch_deg (degrees below level, 0.5..89.5) is required");
  const auto optional_number = [&](const char* key, double& out) {
    return fs[key].empty() || read_number(fs[key], out);
  };
  if (!optional_number("mount_roll_deg", roll) || !optional_number("mount_yaw_deg", yaw) ||
      !optional_number("mount_x", m.x_m) || !optional_number("mount_y", m.y_m))
    return error("mount_roll_deg, mount_yaw_deg, mount_x and mount_y must be numbers");
  m.pitch_rad = pitch * kRadiansPerDegree;
  m.roll_rad = roll * kRadiansPerDegree;
  m.yaw_rad = yaw * kRadiansPerDegree;
  return m;
}

// A pinhole camera: camera_matrix, distortion and the mounting.
Result<CameraModel> read_pinhole_camera(const cv::FileStorage& fs, ImageSize size) {
  Result<PinholeIntrinsics> k = read_intrinsics(fs, size);
  if (!k) return k.error();
  Result<CameraMounting> m = read_mounting(fs);
  if (!m) return m.error();
  CameraModel model = CameraModel::pinhole(size.width, size.height, *k, *m);
  if (!sees_road(model))
    return error(
        "the camera sees no road: no ground point 5 to 20 m ahead of the car, within 3 m of its "
        "axis, falls inside the image (check camera_matrix and the mount angles)");
  return model;
}

// The camera a calibration file describes; errors say what is wrong, not where.
Result<CameraModel> read_camera(const cv::FileStorage& fs) {
  Result<ImageSize> size = read_image_size(fs);
  if (!size) return size.error();
  if (!fs["ground_homography"].empty()) return read_homography_camera(fs, *size);
  return read_pinhole_camera(fs, *size);
}

}  // namespace

Result<CameraModel> load_camera_model(const std::string& path) {
  // FileStorage reports syntax errors by throwing cv::Exception; they stop
  // here, at start-up, never in the loop.
  try {
    Result<cv::FileStorage> storage = open_storage_file(path);
    if (!storage) return storage.error();
    Result<CameraModel> model = read_camera(*storage);
    if (!model) return with_context(path, model.error());
    return model;
  } catch (const std::exception& e) {
    return error(path + ": " + e.what());
  }
}

Status save_camera_model(const CameraModel& model, const std::string& path) {
  try {
    cv::FileStorage fs(path, cv::FileStorage::WRITE);
    if (!fs.isOpened()) return error(path + ": cannot open for writing");
    fs << "image_width" << model.width() << "image_height" << model.height();
    if (!model.is_pinhole()) {
      cv::Mat H(3, 3, CV_64F);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) H.at<double>(r, c) = model.image_to_ground_homography()(r, c);
      fs << "ground_homography" << H;
      return {};
    }
    const auto& k = model.intrinsics();
    const auto& m = model.mounting();
    fs << "camera_matrix" << (cv::Mat_<double>(3, 3) << k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
    fs << "distortion_coefficients"
       << (cv::Mat_<double>(1, 5) << k.distortion[0], k.distortion[1], k.distortion[2], k.distortion[3],
           k.distortion[4]);
    fs << "mount_x" << m.x_m << "mount_y" << m.y_m << "mount_height" << m.height_m;
    fs << "mount_pitch_deg" << m.pitch_rad / kRadiansPerDegree << "mount_roll_deg"
       << m.roll_rad / kRadiansPerDegree << "mount_yaw_deg" << m.yaw_rad / kRadiansPerDegree;
    return {};
  } catch (const std::exception& e) {
    return error(path + ": " + e.what());
  }
}

CameraModel default_camera_model() {
  PinholeIntrinsics k;
  k.fx = k.fy = 900.0;
  k.cx = 639.5;
  k.cy = 255.5;
  k.distortion = {-0.05, 0.01, 0.0, 0.0, 0.0};
  CameraMounting m;
  m.height_m = 1.5;
  m.pitch_rad = 12.0 * kRadiansPerDegree;
  return CameraModel::pinhole(1280, 512, k, m);
}

}  // namespace markloop::perception
