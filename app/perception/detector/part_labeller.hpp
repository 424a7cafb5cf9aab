// Part labelling, the detector's second stage: the paint mask's connected
// regions (8-connected, run-length union-find) become parts, with their
// boxes and second moments. Thin long parts (lane lines, kerbs) and large
// sparse ones are set apart: never grouped, never classified; those short
// enough to be a letter's stroke are kept as strokes for the grouping.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "app/perception/birdseye.hpp"
#include "app/perception/detector/candidate.hpp"
#include "app/perception/detector/detector_config.hpp"
#include "app/perception/detector/detector_counters.hpp"
#include "app/perception/detector/lane_horizon.hpp"

namespace markloop::perception {

class PartLabeller {
 public:
  // For masks of rows x cols pixels of `region`; strokes are line parts no
  // longer than `stroke_max_length_m`.
  PartLabeller(const PartConfig& config, float stroke_max_length_m, const BirdsEyeRegion& region, int rows,
               int cols);

  // The parts of `mask` (CV_8UC1, 255 = paint), at most kMaxParts. Lane
  // lines go to `lanes` when given. Returns how many parts.
  std::size_t label(const cv::Mat& mask, LaneHorizon* lanes, DetectorCounters& counters);

  // The last label()'s parts and strokes.
  std::span<const Part> parts() const { return {parts_.data(), part_count_}; }
  std::span<const Part> strokes() const { return {strokes_.data(), stroke_count_}; }

 private:
  // Sums over a provisional label's pixels, for its axis.
  struct Moments {
    std::int64_t row, col, row_row, col_col, row_col;
  };
  // Provisional labels for the mask's pixels; returns how many.
  int label_pixels(const cv::Mat& mask);
  void label_row(const cv::Mat& mask, int r, int& next);
  void add_pixel(int label, int r, int c);
  void merge_into_roots(int labels);
  // Keeps the root labels' parts; sets lines apart.
  void keep_parts(const cv::Mat& mask, int labels, LaneHorizon* lanes, DetectorCounters& counters);
  // True when the part is a line or a kerb (set apart), counted and, when
  // short enough for a letter, kept as a stroke.
  bool set_apart_as_line(const cv::Mat& mask, int label, const PartAxis& part_axis,
                         DetectorCounters& counters);
  PartAxis axis(const Part& box, const Moments& sums) const;
  // True when the paint of `label` (a root label) encloses road of at least
  // kMinEnclosedM2 inside its box: a closed outline (a diamond), no line.
  bool encloses_road(const cv::Mat& mask, int label, const Part& box);

  PartConfig config_;
  float stroke_max_length_m_;
  float x_step_m_, y_step_m_;
  int min_part_area_px_ = 1;
  std::vector<std::int32_t> pixel_labels_;  // provisional label per pixel, -1 none
  std::vector<std::int32_t> parent_;        // union-find over provisional labels
  std::vector<Part> label_box_;             // box and area per provisional label
  std::vector<Moments> label_moments_;      // pixel sums per provisional label
  std::vector<std::uint8_t> fill_reached_;  // encloses_road(): pixels reached from the box's border
  std::vector<std::int32_t> fill_queue_;    // ... and those still to visit
  std::vector<Part> parts_;                 // kMaxParts
  std::size_t part_count_ = 0;
  std::array<Part, kMaxStrokes> strokes_{};  // line parts short enough to be a letter
  std::size_t stroke_count_ = 0;
};

}  // namespace markloop::perception
