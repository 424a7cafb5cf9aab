// Readers for the file formats of the paper's published dataset and of the
// simulator's ground truth. Every error names the file and line.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "app/common/result.hpp"
#include "app/engine/types.hpp"

namespace markloop::replay {

// One record of road_marking_centroids_3Dposition.txt: a detection in frame
// `frame` at (x, y, z) in camera-style world axes (x right, y down, z ahead).
struct MarkingRecord {
  std::int32_t frame = 0;
  float x = 0.0f;
  float y = 0.0f;
  float z = 0.0f;
  std::string label;
  int line = 0;         // in its file; 0: not known
  float weight = 1.0f;  // Observation::weight
  // Observation::facing. The file holds markings read as painted: facing
  // the car, unless a half turn leaves the class alike or it is not one of
  // markloop's classes (facing_read_upright).
  Facing facing = Facing::kAny;
};

// The facing of a marking of class `label` read as painted.
Facing facing_read_upright(std::string_view label);

// Interns label names into the engine's opaque label ids.
class LabelTable {
 public:
  Label intern(const std::string& name);
  const std::string& name(Label label) const { return names_.at(label); }
  std::size_t size() const { return names_.size(); }

 private:
  std::vector<std::string> names_;
  std::unordered_map<std::string, Label> ids_;
};

// Each file is read whole, so each has a limit, checked before it is read:
// several times the paper's whole dataset (its 200 drives in one file).
inline constexpr std::size_t kMaxMarkingsBytes = std::size_t{256} << 20;
inline constexpr std::size_t kMaxPosesBytes = std::size_t{256} << 20;  // poses and truth
// A pose coordinate farther from the origin than this (metres) is no pose of
// a drive (a file in other units, or garbage); refused, so that distances
// and grid cells computed from poses stay finite.
inline constexpr double kMaxPoseCoordinate_m = 1e8;
// frames.csv's yaw may be unwrapped (turns add up), not without end; its
// time is seconds since the start, within a century of driving.
inline constexpr double kMaxYaw_rad = 1e6;
inline constexpr double kMaxTime_s = 3.2e9;
// Labels are class names: a longer one is no label (a line gone wrong).
inline constexpr std::size_t kMaxLabelLength = 64;

// Each loader returns an error ("FILE:LINE: what") on bad input ("FILE:
// what" when the file cannot be read, is a directory or is too big).
Result<std::vector<MarkingRecord>> load_markings(const std::string& path);
// One 3x4 row-major [R|t] camera pose per line (KITTI odometry), line i for
// frame i, converted to the ground frame (x ahead = z, y left = -x).
Result<std::vector<Pose2>> load_kitti_poses(const std::string& path);

// Ground truth: a pose per frame and, from the simulator's frames.csv, its
// time (none from KITTI poses, which carry no time).
struct TruePoses {
  std::vector<Pose2> poses;
  std::vector<double> times;
};
// The simulator's frames.csv (header frame,t,x,y,yaw) or KITTI poses.
Result<TruePoses> load_truth(const std::string& path);
// The simulator's frames.csv only (its header required).
Result<TruePoses> load_frames_csv(const std::string& path);

// The paper's camera-style axes to the engine's ground frame.
inline Observation to_ground(const MarkingRecord& r, Label label) {
  return {label, r.z, -r.x, r.weight, r.facing};
}

}  // namespace markloop::replay
