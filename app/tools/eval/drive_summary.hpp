// markloop-eval --summary: the figures of many drives (their eval.json
// files) summed into the table issue 64's targets are read on: revisit
// events closed by kind and length, closure distances, wrong loop
// detections and the relative pose error.
#pragma once

#include <cstddef>
#include <cstdio>
#include <string>
#include <vector>

#include "app/common/result.hpp"
#include "app/tools/replay/revisit_events.hpp"

namespace markloop::eval {

// What the summary takes from one drive's eval.json.
struct DriveFigures {
  std::string name;  // the file as given
  double route_length_m = 0.0;
  std::size_t wrong = 0;
  std::size_t pose_errors = 0;  // correct detections with a pose
  double translation_error_mean_m = 0.0;
  std::vector<replay::RevisitEvent> events;
};

// An eval.json of markloop-eval (with its "revisits"); else "FILE: what".
Result<DriveFigures> load_drive_figures(const std::string& path);

struct DriveWithWrongLoops {
  std::string name;
  std::size_t wrong = 0;
};

struct DrivesSummary {
  std::size_t drives = 0;
  double route_length_m = 0.0;
  replay::RevisitTally tally;  // over every drive's events
  std::size_t wrong = 0;
  std::size_t pose_errors = 0;
  double translation_error_mean_m = 0.0;  // over all detections with a pose, not per drive
  std::vector<DriveWithWrongLoops> with_wrong_loops;
};

DrivesSummary summarise_drives(const std::vector<DriveFigures>& drives);

void print_drives_summary(std::FILE* out, const DrivesSummary& summary);
Status write_drives_summary_json(const std::string& path, const DrivesSummary& summary);

}  // namespace markloop::eval
