// The lane lines of a frame, as the part labelling sets them apart, and
// where they place the road's horizon (horizon.hpp): the detector reads the
// view higher or lower by the difference from the calibration's.
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <span>

#include "app/perception/birdseye.hpp"
#include "app/perception/camera_model.hpp"
#include "app/perception/detector/candidate.hpp"
#include "app/perception/horizon.hpp"

namespace markloop::perception {

class LaneHorizon {
 public:
  // `camera` and `view` must outlive this; `view` may move (its row shift).
  LaneHorizon(const CameraModel& camera, const BirdsEyeView& view, const BirdsEyeRegion& region,
              int max_shift_px);

  // True when the calibration places the horizon straight ahead.
  bool known() const { return known_; }

  void clear() { count_ = 0; }
  // A part of the view, kept as a lane line in the image when it is long
  // and thin along the road (the longest kMaxHorizonSegments).
  void note(const PartAxis& axis);
  // Image rows the horizon lies below the calibration's, from the lines
  // noted; none when they do not meet near it.
  std::optional<float> measure_shift() const;

  std::span<const ImageSegment> segments() const { return {segments_.data(), count_}; }

 private:
  const CameraModel& camera_;
  const BirdsEyeView& view_;
  float x_step_m_, y_step_m_;
  int max_shift_px_;
  float calibrated_row_ = 0.0f;  // the image row of the road's horizon, straight ahead
  bool known_ = false;
  std::array<ImageSegment, kMaxHorizonSegments> segments_{};
  std::array<float, kMaxHorizonSegments> lengths_{};
  std::size_t count_ = 0;
};

}  // namespace markloop::perception
