// Location, the detector's last stage: a candidate's box in the bird's-eye
// view placed on the ground (its centre, vehicle frame) and in the image
// (its quad), and whether its centre lies in the guard band beyond the
// region searched.
#pragma once

#include "app/perception/birdseye.hpp"
#include "app/perception/camera_model.hpp"
#include "app/perception/detector/candidate.hpp"

namespace markloop::perception {

class MarkingLocator {
 public:
  // `camera` and `view` must outlive this; `view` may move (its row shift).
  MarkingLocator(const CameraModel& camera, const BirdsEyeView& view, const BirdsEyeRegion& region);

  // The quad (image pixels) and ground centre of a candidate's box.
  void locate(const Candidate& candidate, Detection& out) const;
  // True when the candidate's centre lies beyond `region`, in the guard band.
  bool beyond_region(const Candidate& candidate) const;

 private:
  // A candidate's box on the ground (vehicle frame, metres).
  struct GroundBox {
    float far, near, left, right;
  };
  GroundBox ground_box(const Candidate& candidate) const;

  const CameraModel& camera_;
  const BirdsEyeView& view_;
  BirdsEyeRegion region_;
};

}  // namespace markloop::perception
