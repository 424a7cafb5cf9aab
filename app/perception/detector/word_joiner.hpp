// Word joining, the detector's fifth stage (after classification): a word
// painted on the road may fall in several candidates (its letters either
// side of a letter set apart as a line, or a little too far apart to
// group), each classified as the word; they are reported as one detection.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "app/perception/birdseye.hpp"
#include "app/perception/detector/candidate.hpp"
#include "app/perception/detector/detector_config.hpp"

namespace markloop::perception {

// After classification: reported_by[i] = the candidate whose detection
// candidate i is part of: the first of a word's candidates linked left to
// right by across_stroke and classified alike (passing over up to two of
// other classes between them, rejected or not: a letter broken by a
// shadow, which join the word too), or i itself. Returns how many
// candidates of the word's class joined another's detection.
std::size_t join_across_strokes(std::span<const Candidate> candidates, std::span<std::int32_t> reported_by);
// True for the classes painted as words or numbers (stop, ped, xing, the
// word BIKE or the bicycle, 25, 35, 40).
bool is_word_class(int label);
// After join_across_strokes(): of the whole candidates joined to no other,
// those of a word class side by side with one of the same class (sharing
// min_shared of the shorter one's rows, at most half as long again) up to
// gap_cols apart, directly or through others so, while at most max_cols
// across together, are reported by the first. Returns how many joined
// another's detection.
std::size_t join_split_words(std::span<const Candidate> candidates, std::span<std::int32_t> reported_by,
                             int gap_cols, int max_cols, float min_shared);
// True when another candidate is part of candidate `first`'s detection:
// `first` reports a word joined from several candidates.
bool reports_others(std::span<const std::int32_t> reported_by, std::size_t first);
// Candidate `first` grown by those reported by it: their boxes joined, the
// highest score of its class, cut by the view's edge where any of them is.
Candidate joined_candidate(std::span<const Candidate> candidates, std::span<const std::int32_t> reported_by,
                           std::size_t first);

class WordJoiner {
 public:
  WordJoiner(const WordConfig& config, float min_shared, const BirdsEyeRegion& region);

  // join_across_strokes(), then join_split_words() with the configured
  // gaps; returns how many candidates joined another's detection.
  std::size_t join(std::span<const Candidate> candidates, std::span<std::int32_t> reported_by) const;

 private:
  int gap_cols_ = 0, max_cols_ = 0;  // word_join_gap_m, word_max_width_m
  float min_shared_;                 // GroupingConfig::stroke_min_shared
};

}  // namespace markloop::perception
