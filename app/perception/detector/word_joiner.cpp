#include "app/perception/detector/word_joiner.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string_view>

#include "app/perception/marking_classes.hpp"
#include "app/perception/marking_classifier.hpp"

namespace markloop::perception {

WordJoiner::WordJoiner(const WordConfig& config, float min_shared, const BirdsEyeRegion& region)
    : gap_cols_(static_cast<int>(std::lround(config.word_join_gap_m / region.y_step_m))),
      max_cols_(static_cast<int>(std::lround(config.word_max_width_m / region.y_step_m))),
      min_shared_(min_shared) {}

std::size_t WordJoiner::join(std::span<const Candidate> candidates,
                             std::span<std::int32_t> reported_by) const {
  const std::size_t across = join_across_strokes(candidates, reported_by);
  return across + join_split_words(candidates, reported_by, gap_cols_, max_cols_, min_shared_);
}

std::size_t join_across_strokes(std::span<const Candidate> candidates, std::span<std::int32_t> reported_by) {
  const std::size_t n = std::min({candidates.size(), reported_by.size(), kMaxCandidates});
  const auto valid = [&](int i) { return i >= 0 && static_cast<std::size_t>(i) < n; };
  // The next candidate of i's class across the strokes to the right of
  // `i`, passing over at most kMaxBrokenLetters of other classes (a letter
  // broken by a shadow, its pieces taken for no marking; the diagonal of an
  // N between its upright and the I, taken for something else); -1 none.
  constexpr int kMaxBrokenLetters = 2;
  const auto next_marking = [&](std::size_t i) {
    int next = candidates[i].across_stroke;
    for (int hops = 0;
         valid(next) && candidates[static_cast<std::size_t>(next)].predicted != candidates[i].predicted;
         ++hops)
      next = hops < kMaxBrokenLetters ? candidates[static_cast<std::size_t>(next)].across_stroke : -1;
    return valid(next) ? next : -1;
  };
  const auto links_alike = [&](std::size_t i, int next) {
    return next >= 0 && candidates[i].predicted != kRejectClass &&
           candidates[static_cast<std::size_t>(next)].predicted == candidates[i].predicted;
  };
  for (std::size_t i = 0; i < n; ++i) reported_by[i] = static_cast<std::int32_t>(i);
  // A word starts where no candidate classified alike links to it.
  std::array<bool, kMaxCandidates> linked_to{};
  for (std::size_t i = 0; i < n; ++i)
    if (const int next = next_marking(i); links_alike(i, next))
      linked_to[static_cast<std::size_t>(next)] = true;
  std::size_t joined = 0;
  for (std::size_t first = 0; first < n; ++first) {
    if (linked_to[first]) continue;
    for (std::size_t at = first;;) {
      const int next = next_marking(at);
      if (!links_alike(first, next) || reported_by[static_cast<std::size_t>(next)] != next) break;
      // The broken letters on the way belong to the word too.
      for (int piece = candidates[at].across_stroke; piece != next;
           piece = candidates[static_cast<std::size_t>(piece)].across_stroke)
        if (reported_by[static_cast<std::size_t>(piece)] == piece)
          reported_by[static_cast<std::size_t>(piece)] = static_cast<std::int32_t>(first);
      reported_by[static_cast<std::size_t>(next)] = static_cast<std::int32_t>(first);
      ++joined;
      at = static_cast<std::size_t>(next);
    }
  }
  return joined;
}

bool is_word_class(int label) {
  static constexpr auto kWords = [] {
    std::array<bool, kMarkingClassCount> words{};
    for (const std::string_view name : {"stop", "ped", "xing", "bike", "25", "35", "40"})
      words[*marking_class_from_name(name)] = true;
    return words;
  }();
  return label >= 0 && label < static_cast<int>(kMarkingClassCount) &&
         kWords[static_cast<std::size_t>(label)];
}

std::size_t join_split_words(std::span<const Candidate> candidates, std::span<std::int32_t> reported_by,
                             int gap_cols, int max_cols, float min_shared) {
  const std::size_t n = std::min({candidates.size(), reported_by.size(), kMaxCandidates});
  // Alone: neither reports another nor is reported by one.
  std::array<bool, kMaxCandidates> alone{};
  for (std::size_t i = 0; i < n; ++i) alone[i] = reported_by[i] == static_cast<std::int32_t>(i);
  for (std::size_t i = 0; i < n; ++i)
    if (reported_by[i] != static_cast<std::int32_t>(i))
      alone[static_cast<std::size_t>(reported_by[i])] = false;
  // Letters of one word: close across, along most of the shorter one's
  // rows, and at most half as long again. (Whole ones only: a lane dash
  // coming into view beside a word is no letter of it, whatever it is
  // taken for.)
  const auto beside = [&](const Candidate& a, const Candidate& b) {
    const int gap = std::max(b.col0 - a.col1, a.col0 - b.col1) - 1;
    const int shared = rows_shared(a, b);
    const int shorter = std::min(rows_of(a), rows_of(b));
    const int longer = std::max(rows_of(a), rows_of(b));
    return gap >= 0 && gap <= gap_cols && 2 * longer <= 3 * shorter &&
           static_cast<float>(shared) >= min_shared * static_cast<float>(shorter);
  };
  const auto letter_of = [&](std::size_t i, int label) {
    return alone[i] && candidates[i].predicted == label && !candidates[i].clipped;
  };
  std::size_t joined = 0;
  std::array<std::size_t, kMaxCandidates> word{};  // the word's candidates, first first
  for (std::size_t first = 0; first < n; ++first) {
    const int label = candidates[first].predicted;
    if (!is_word_class(label) || !letter_of(first, label)) continue;
    std::size_t letters = 1;
    word[0] = first;
    int col0 = candidates[first].col0, col1 = candidates[first].col1;
    // The word grows by the letters beside any of its own, while narrow
    // enough to be one word.
    for (bool grew = true; grew;) {
      grew = false;
      for (std::size_t j = 0; j < n; ++j) {
        const Candidate& letter = candidates[j];
        if (j == first || !letter_of(j, label)) continue;
        if (std::max(col1, letter.col1) - std::min(col0, letter.col0) + 1 > max_cols) continue;
        const auto next_to = [&](std::size_t member) { return beside(candidates[member], letter); };
        if (std::none_of(word.begin(), word.begin() + static_cast<std::ptrdiff_t>(letters), next_to))
          continue;
        reported_by[j] = static_cast<std::int32_t>(first);
        alone[j] = false;
        word[letters++] = j;
        col0 = std::min(col0, letter.col0);
        col1 = std::max(col1, letter.col1);
        ++joined;
        grew = true;
      }
    }
    if (letters > 1) alone[first] = false;
  }
  return joined;
}

bool reports_others(std::span<const std::int32_t> reported_by, std::size_t first) {
  for (std::size_t j = 0; j < reported_by.size(); ++j)
    if (j != first && reported_by[j] == static_cast<std::int32_t>(first)) return true;
  return false;
}

Candidate joined_candidate(std::span<const Candidate> candidates, std::span<const std::int32_t> reported_by,
                           std::size_t first) {
  Candidate c = candidates[first];
  const float metres_per_row = c.length_m / static_cast<float>(rows_of(c));
  const float metres_per_col = c.width_m / static_cast<float>(cols_of(c));
  bool cut_elsewhere = c.clipped && !c.clipped_near_only;
  for (std::size_t j = 0; j < candidates.size() && j < reported_by.size(); ++j) {
    if (j == first || reported_by[j] != static_cast<std::int32_t>(first)) continue;
    const Candidate& other = candidates[j];
    grow_box(c, other);
    c.parts += other.parts;
    if (other.predicted == c.predicted) c.score = std::max(c.score, other.score);
    c.clipped = c.clipped || other.clipped;
    cut_elsewhere = cut_elsewhere || (other.clipped && !other.clipped_near_only);
  }
  c.length_m = metres_per_row * static_cast<float>(rows_of(c));
  c.width_m = metres_per_col * static_cast<float>(cols_of(c));
  c.clipped_near_only = c.clipped && !cut_elsewhere;
  return c;
}

}  // namespace markloop::perception
