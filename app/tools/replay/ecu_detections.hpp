// The ECU's detections (its --detections-out CSV) as replay records: each
// placed on the ground with the pose of its frame and gated as the ECU gates
// them (app/ecu/observation.hpp). With the ECU's own odometry as the poses
// (markloop-posegraph's before.kitti), the replay feeds the engine what the
// car's engine was fed, and settings can be tried on a recorded drive.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "app/common/result.hpp"
#include "app/ecu/config.hpp"
#include "app/engine/types.hpp"
#include "app/tools/replay/paper_format.hpp"

namespace markloop::replay {

struct EcuDetections {
  std::vector<MarkingRecord> records;  // the observed ones, in frame order
  std::size_t detections = 0;          // in the file
  std::size_t gated = 0;               // refused by the gate
};

// A malformed line is an error ("FILE:LINE: what"), as is a frame beyond `poses`.
Result<EcuDetections> load_ecu_detections(const std::string& path, const std::vector<Pose2>& poses,
                                          const ecu::ObservationGate& gate);

}  // namespace markloop::replay
