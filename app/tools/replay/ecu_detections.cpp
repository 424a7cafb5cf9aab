#include "app/tools/replay/ecu_detections.hpp"

#include <limits>

#include "app/ecu/observation.hpp"
#include "app/perception/marking_classes.hpp"
#include "app/tools/eval/inputs.hpp"

namespace markloop::replay {

Result<EcuDetections> load_ecu_detections(const std::string& path, const std::vector<Pose2>& poses,
                                          const ecu::ObservationGate& gate) {
  Result<std::vector<eval::DetectionRecord>> loaded =
      eval::load_detections(path, std::numeric_limits<FrameIndex>::max());
  if (!loaded) return loaded.error();
  if (!loaded->empty() && loaded->back().frame >= poses.size())
    return error(path + ": frame " + std::to_string(loaded->back().frame) + " has no pose (the poses hold " +
                 std::to_string(poses.size()) + " frames)");
  EcuDetections out;
  out.detections = loaded->size();
  out.records.reserve(loaded->size());
  for (const eval::DetectionRecord& d : *loaded) {
    Observation o;
    if (ecu::observe(d.label, static_cast<float>(d.score), d.turned, d.ground_x, d.ground_y, poses[d.frame],
                     gate, o) != ecu::Observed::kYes) {
      ++out.gated;
      continue;
    }
    // The paper's camera-style axes: x right, z ahead.
    MarkingRecord r;
    r.frame = static_cast<std::int32_t>(d.frame);
    r.x = -o.y;
    r.z = o.x;
    r.label = std::string(perception::marking_class_name(d.label));
    r.weight = o.weight;
    r.facing = o.facing;
    out.records.push_back(std::move(r));
  }
  return out;
}

}  // namespace markloop::replay
