// Plain data exchanged with the sequence engine. Units: metres, seconds,
// radians. The world frame is a 2-D ground frame (x, y) whose drift is slow.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>

namespace markloop {

// A marking class id. The engine treats labels as opaque; the classifier and
// the replay tool own the mapping to names.
using Label = std::uint16_t;
using FrameIndex = std::uint32_t;
// Monotonic id of a committed landmark; never reused within a session.
using LandmarkId = std::uint32_t;
inline constexpr LandmarkId kNoLandmark = std::numeric_limits<LandmarkId>::max();

// Maximum sequence length the engine is built for (the paper sweeps 2..10).
inline constexpr unsigned kMaxSequenceLength = 10;

struct Pose2 {
  double x = 0.0;
  double y = 0.0;
  double yaw = 0.0;
};

// Composition and inverse of planar rigid transforms.
Pose2 compose(const Pose2& a, const Pose2& b);
Pose2 inverse(const Pose2& p);
double wrap_angle(double radians);

// Which way a marking is painted, as the camera read it: for the car's
// direction of travel (kAlong) or for the opposite one (kAgainst, read
// upside down). A marking that a half turn leaves alike (a crosswalk, a stop
// line) has no facing (kAny). Two landmarks facing opposite ways on the
// ground are two markings, whatever their labels.
// The values are stored in map files.
enum class Facing : std::uint8_t { kAny = 0, kAlong = 1, kAgainst = 2 };

// One detected marking in one frame, already placed on the ground.
struct Observation {
  Label label = 0;
  float x = 0.0f;  // world frame, metres
  float y = 0.0f;
  // Relative precision of the position (inverse variance, any scale, > 0):
  // a camera places near markings better than far ones.
  float weight = 1.0f;
  Facing facing = Facing::kAny;  // against the car's heading in this frame
};

struct FrameInput {
  FrameIndex frame = 0;
  double t = 0.0;         // seconds
  bool has_pose = false;  // the car's pose in the world frame, when known
  Pose2 pose{};
};

// A physical marking, fused from its observations, as stored in the database.
struct Landmark {
  LandmarkId id = kNoLandmark;
  Label label = 0;
  std::uint16_t observations = 0;
  FrameIndex first_frame = 0;
  // The frame that represents the landmark: the one in which the car came
  // closest to it when the pose is known (the same spot on every visit),
  // else its last sighting.
  FrameIndex last_frame = 0;
  float x = 0.0f;  // world position, metres
  float y = 0.0f;
  float car_x = 0.0f;  // the car's pose at last_frame, when known
  float car_y = 0.0f;
  float car_yaw = 0.0f;
  bool has_car_pose = false;
  Facing facing = Facing::kAny;  // against car_yaw
  double t = 0.0;                // time of last_frame, seconds
  double station = 0.0;          // distance travelled along the drive, metres
};

// The car at the query seen from the car at the match, both where they came
// closest to their landmark, once `alignment` maps the match's world frame
// onto the query's; none when either car's pose is unknown.
std::optional<Pose2> relative_car_pose(const Pose2& alignment, const Landmark& query, const Landmark& match);

// Gives `landmark` the frame that represents `passed` (the same marking):
// its frame, time, car pose and facing.
void copy_frame(const Landmark& passed, Landmark& landmark);

// The direction on the ground a landmark's marking is painted for, in its
// world frame; none when it has no facing or no car pose.
std::optional<double> facing_yaw(const Landmark& landmark);

}  // namespace markloop
