#include "app/perception/detector/crosswalk_joiner.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "app/perception/marking_classes.hpp"

namespace markloop::perception {
namespace {

const int kStopline = static_cast<int>(*marking_class_from_name("stopline"));
const int kCrosswalk = static_cast<int>(*marking_class_from_name("crosswalk"));

float centre_row(const Candidate& c) {
  return 0.5f * static_cast<float>(c.row0 + c.row1);
}

}  // namespace

CrosswalkJoiner::CrosswalkJoiner(const SideCrosswalkConfig& config, float bar_max_length_m,
                                 const BirdsEyeRegion& region, const ViewEdges& edges)
    : config_(config),
      edges_(edges),
      bar_max_rows_(static_cast<int>(std::lround(bar_max_length_m / region.x_step_m))),
      metres_per_row_(region.x_step_m) {}

std::size_t CrosswalkJoiner::join(std::span<Candidate> candidates,
                                  std::span<std::int32_t> reported_by) const {
  if (!config_.side_crosswalks) return 0;
  const std::size_t n = std::min({candidates.size(), reported_by.size(), kMaxCandidates});
  std::array<int, kMaxCandidates> bars{};
  std::size_t bar_count = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Candidate& c = candidates[i];
    if (reported_by[i] == static_cast<std::int32_t>(i) && c.predicted == kStopline &&
        rows_of(c) <= bar_max_rows_)
      bars[bar_count++] = static_cast<int>(i);
  }
  const std::span<int> sorted(bars.data(), bar_count);
  std::sort(sorted.begin(), sorted.end(), [&](int a, int b) {
    return centre_row(candidates[static_cast<std::size_t>(a)]) <
           centre_row(candidates[static_cast<std::size_t>(b)]);
  });
  std::size_t joined = 0;
  std::array<int, kMaxCandidates> stack{};
  std::array<bool, kMaxCandidates> taken{};  // by sorted position: in a stack found before
  for (std::size_t first = 0; first < bar_count; ++first) {
    if (taken[first]) continue;
    const std::size_t length = stack_from(candidates, sorted, taken, first, stack);
    if (length < static_cast<std::size_t>(config_.side_crosswalk_min_bars)) continue;
    for (std::size_t k = 0; k < length; ++k) taken[static_cast<std::size_t>(stack[k])] = true;
    const auto index = [&](std::size_t k) {  // the candidate of the stack's k-th bar
      return static_cast<std::size_t>(sorted[static_cast<std::size_t>(stack[k])]);
    };
    const auto bar = [&](std::size_t k) -> Candidate& { return candidates[index(k)]; };
    const int pitch_rows = static_cast<int>(std::lround(centre_row(bar(length - 1)) - centre_row(bar(0)))) /
                           static_cast<int>(length - 1);
    Candidate& crosswalk = bar(0);
    crosswalk.predicted = kCrosswalk;
    crosswalk.turned = false;
    if (!seen_moved(bar(0), -pitch_rows) || !seen_moved(bar(length - 1), pitch_rows)) {
      crosswalk.clipped = true;  // may go on unseen
      crosswalk.clipped_near_only = false;
    }
    for (std::size_t k = 1; k < length; ++k) reported_by[index(k)] = static_cast<std::int32_t>(index(0));
    joined += length - 1;
  }
  return joined;
}

std::size_t CrosswalkJoiner::stack_from(std::span<const Candidate> candidates, std::span<const int> bars,
                                        std::span<const bool> taken, std::size_t first,
                                        std::span<int> stack) const {
  const auto bar = [&](std::size_t k) -> const Candidate& {
    return candidates[static_cast<std::size_t>(bars[k])];
  };
  std::size_t length = 0;
  stack[length++] = static_cast<int>(first);
  float first_pitch = 0.0f;
  for (std::size_t k = first + 1; k < bars.size(); ++k) {
    const Candidate& last = bar(static_cast<std::size_t>(stack[length - 1]));
    const Candidate& next = bar(k);
    const float pitch = (centre_row(next) - centre_row(last)) * metres_per_row_;
    if (pitch > config_.side_crosswalk_pitch_max_m) break;  // sorted: the rest lie further on
    const int narrower = std::min(cols_of(last), cols_of(next));
    const bool beside = static_cast<float>(cols_shared(last, next)) >=
                        config_.side_crosswalk_min_shared * static_cast<float>(narrower);
    const bool even =
        length == 1 || std::abs(pitch - first_pitch) <= config_.side_crosswalk_pitch_tolerance * first_pitch;
    if (taken[k] || !beside || pitch < config_.side_crosswalk_pitch_min_m || !even) continue;
    if (length == 1) first_pitch = pitch;
    stack[length++] = static_cast<int>(k);
  }
  return length;
}

bool CrosswalkJoiner::seen_moved(const Candidate& bar, int rows) const {
  const cv::Mat& valid = edges_.valid_integral();  // (rows + 1) x (cols + 1)
  const int row0 = bar.row0 + rows, row1 = bar.row1 + rows;
  if (row0 < 0 || bar.col0 < 0 || row1 + 1 >= valid.rows || bar.col1 + 1 >= valid.cols) return false;
  const auto at = [&](int r, int c) { return valid.at<std::int32_t>(r, c); };
  const int seen =
      at(row1 + 1, bar.col1 + 1) - at(row0, bar.col1 + 1) - at(row1 + 1, bar.col0) + at(row0, bar.col0);
  return seen == rows_of(bar) * cols_of(bar);
}

}  // namespace markloop::perception
