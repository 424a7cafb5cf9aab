// What the detector did, frame by frame, counted: its stages add to these
// instead of logging on the per-frame path.
#pragma once

#include <cstdint>

namespace markloop::perception {

struct DetectorCounters {
  std::uint64_t frames = 0;
  std::uint64_t bad_frames = 0;           // wrong size or type: not processed
  std::uint64_t flat_frames = 0;          // ViewKind::Flat
  std::uint64_t noisy_frames = 0;         // ViewKind::Noisy
  std::uint64_t cluttered_frames = 0;     // ViewKind::Cluttered
  std::uint64_t detections_withheld = 0;  // found in cluttered frames: not reported
  std::uint64_t parts = 0;                // connected bright regions kept
  std::uint64_t parts_dropped = 0;        // over capacity (kMaxParts)
  std::uint64_t lane_lines = 0;           // thin long parts set apart
  std::uint64_t strokes_dropped = 0;      // ... short enough to be a letter, over kMaxStrokes
  std::uint64_t joined = 0;               // candidates in another's detection (a word, a side crosswalk)
  std::uint64_t candidates = 0;           // groups classified
  std::uint64_t candidates_dropped = 0;   // over capacity (kMaxCandidates)
  std::uint64_t oversize = 0;             // parts or groups too large to be a marking
  std::uint64_t clipped = 0;              // groups cut by the region's or the image's edge, left out
  std::uint64_t partial = 0;              // ... cut by the near edge, reported by detect_still()
  std::uint64_t rejected = 0;             // classifier said: not a marking
  std::uint64_t low_score = 0;            // marking class below min_score
  std::uint64_t pieces = 0;               // inside a larger marking (is_piece_of_larger)
  std::uint64_t beyond_region = 0;        // whole, but centred in the guard band (guard_m)
  std::uint64_t detections = 0;
  std::uint64_t detections_dropped = 0;  // over kMaxDetections in one frame
  std::uint64_t horizon_measured = 0;    // frames whose lane lines crossed near the horizon
  std::uint64_t horizon_unmeasured = 0;  // ... and frames where they did not
  std::uint64_t horizon_moves = 0;       // row shift of the view changed
};

}  // namespace markloop::perception
