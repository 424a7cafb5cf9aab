// Annotated marking images (the roadmarks-honda layout, which the simulator's
// training-set mode also writes): DIR/annotations.csv with
// `image,label,x1,y1,x2,y2,x3,y3,x4,y4` and the images under DIR/images/.
// Host-only (training and evaluation).
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "app/common/result.hpp"

namespace markloop::perception::train {

struct Annotation {
  std::string label;
  std::array<std::array<float, 2>, 4> quad;  // pixels
};

struct AnnotatedImage {
  std::string name;  // file name under images/, or the frame number of a drive
  std::vector<Annotation> annotations;
  std::vector<bool> in_range;  // per annotation: wholly inside the detector's region
};

// Files read whole, up to these limits (checked first): the real dataset's
// annotations several times over, a long drive's per-frame files.
inline constexpr std::size_t kMaxAnnotationBytes = std::size_t{64} << 20;
inline constexpr std::size_t kMaxDriveFileBytes = std::size_t{256} << 20;

// Images in file-name order, or the error "FILE:LINE: what is wrong"
// ("FILE: what" when it cannot be read, is a directory or is too big).
Result<std::vector<AnnotatedImage>> load_annotations(const std::string& dir);

// A simulator drive (markloop-sim drive): DIR/visible.csv
// (`frame,id,class,x1,y1,...,x4,y4`) as annotations of every `step`-th frame
// of DIR/frames.y4m; names are frame numbers. Its frames must lie among
// DIR/frames.csv's.
Result<std::vector<AnnotatedImage>> load_drive_annotations(const std::string& dir, int step);

// The dataset's clips: frames come in blocks of 60 consecutive numbers
// (roadmark_NNNN.jpg -> (NNNN - 1) / 60); -1 when the name has no number.
int clip_of(const std::string& name);

}  // namespace markloop::perception::train
