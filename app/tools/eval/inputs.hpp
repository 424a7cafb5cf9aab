// Readers for the simulator's truth files and the ECU's detection CSV that
// markloop-eval compares (formats in /tmp/prompts/contracts.md, mirrored in
// the README's Evaluation section). Every reader is strict: a malformed line
// stops it with "FILE:LINE: what is wrong".
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "app/common/result.hpp"
#include "app/engine/types.hpp"

namespace markloop::eval {

// Image quadrilateral, corners in pixels, in file order.
using Quad = std::array<std::array<double, 2>, 4>;

// markings.csv: id,class,x,y,heading (world frame, metres, radians).
struct WorldMarking {
  std::uint32_t id = 0;
  Label label = 0;
  double x = 0.0;
  double y = 0.0;
  double heading = 0.0;
};

// visible.csv: frame,id,class,x1,y1,...,x4,y4 (a marking in view in a frame).
struct VisibleMarking {
  FrameIndex frame = 0;
  std::uint32_t id = 0;
  Label label = 0;
  Quad quad{};
};

// The ECU's --detections-out: frame,label,score,x1,y1,...,x4,y4,ground_x,ground_y
// and turned (1: read turned half way round; files written before it was
// added lack the column: 0).
struct DetectionRecord {
  FrameIndex frame = 0;
  Label label = 0;
  double score = 0.0;
  Quad quad{};
  double ground_x = 0.0;
  double ground_y = 0.0;
  bool turned = false;
};

// The ECU's --landmarks-out: the landmarks in its database at the end,
// label,observations,first_frame,last_frame,x,y,car_x,car_y,car_yaw,has_car_pose
// and facing (x, y and the car's pose at last_frame in the ECU's odometry
// frame; facing Facing's value, missing in files written before it was
// added).
struct LandmarkRecord {
  Label label = 0;
  std::uint32_t observations = 0;
  FrameIndex first_frame = 0;
  FrameIndex last_frame = 0;
  double x = 0.0, y = 0.0;
  double car_x = 0.0, car_y = 0.0, car_yaw = 0.0;
  bool has_car_pose = false;
  Facing facing = Facing::kAny;  // files written before the column: kAny
};

// Reports how far a long read has come on stderr: one line per tenth of the
// file, and only for files of at least `min_lines` lines, so short runs stay
// quiet.
class Progress {
 public:
  Progress(std::string what, std::size_t total_lines, std::size_t min_lines = 200'000);
  void update(std::size_t lines_done);
  void finish();

 private:
  std::string what_;
  std::size_t total_;
  bool enabled_;
  std::size_t next_tenth_ = 1;
};

// Number of lines of a text; for Progress.
std::size_t count_lines(std::string_view text);

// Each of a run's files is read whole, up to this limit (checked first):
// more than half a day of driving in the largest of them.
inline constexpr std::size_t kMaxInputBytes = std::size_t{256} << 20;

// Each returns an error on a file that cannot be read, is a directory or is
// over the limit ("FILE: what"), or on a bad line ("FILE:LINE: what").
// Frames must lie in [0, frame_count) (the truth's frames). Results are
// sorted by frame (stable).
Result<std::vector<WorldMarking>> load_world_markings(const std::string& path);
Result<std::vector<VisibleMarking>> load_visible(const std::string& path, std::size_t frame_count);
Result<std::vector<DetectionRecord>> load_detections(const std::string& path, std::size_t frame_count);
Result<std::vector<LandmarkRecord>> load_landmarks(const std::string& path, std::size_t frame_count);

}  // namespace markloop::eval
