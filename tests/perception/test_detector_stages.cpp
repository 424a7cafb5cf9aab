// The detector's stages one by one, on views drawn by hand.
#include <cstdint>
#include <vector>

#include <catch2/catch_test_macros.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "app/perception/birdseye.hpp"
#include "app/perception/camera_model.hpp"
#include "app/perception/detector/detector_config.hpp"
#include "app/perception/detector/paint_mask.hpp"
#include "app/perception/detector/part_grouper.hpp"
#include "app/perception/detector/part_labeller.hpp"
#include "app/perception/detector/view_edges.hpp"

using namespace markloop::perception;

namespace {

constexpr int kRows = 100, kCols = 80;

// A view of grey road, every pixel seen, and the integral of what is seen.
struct FlatView {
  cv::Mat bev{kRows, kCols, CV_8UC1, cv::Scalar(100)};
  cv::Mat valid{kRows, kCols, CV_8UC1, cv::Scalar(255)};
  cv::Mat valid_integral;
  FlatView() { cv::integral(valid / 255, valid_integral, CV_32S); }
};

// Paint on the mask: rows [row0, row1], columns [col0, col1].
void paint(cv::Mat& mask, int row0, int row1, int col0, int col1) {
  mask(cv::Range(row0, row1 + 1), cv::Range(col0, col1 + 1)).setTo(255);
}

}  // namespace

TEST_CASE("PaintMask finds a bright patch and nothing around it") {
  FlatView view;
  view.bev(cv::Range(40, 60), cv::Range(30, 40)).setTo(200);
  PaintMask paint_mask(DetectorConfig{}, BirdsEyeRegion{}, kRows, kCols);
  paint_mask.find(view.bev, view.valid, view.valid_integral);
  const cv::Mat& mask = paint_mask.mask();
  CHECK(cv::countNonZero(mask) == 20 * 10);
  CHECK(mask.at<std::uint8_t>(50, 35) == 255);
  CHECK(mask.at<std::uint8_t>(10, 10) == 0);
  paint_mask.clear();
  CHECK(cv::countNonZero(paint_mask.mask()) == 0);
}

TEST_CASE("PaintMask cuts a line where a long bar crosses it") {
  FlatView view;
  view.bev(cv::Range::all(), cv::Range(38, 42)).setTo(200);  // 5 m along
  view.bev(cv::Range(50, 55), cv::Range::all()).setTo(200);  // 3.2 m across
  PaintMask paint_mask(DetectorConfig{}, BirdsEyeRegion{}, kRows, kCols);
  paint_mask.find(view.bev, view.valid, view.valid_integral);
  const cv::Mat& mask = paint_mask.mask();
  CHECK(mask.at<std::uint8_t>(52, 39) == 0);  // the crossing
  CHECK(mask.at<std::uint8_t>(46, 39) == 0);  // ... and the margin along the line
  CHECK(mask.at<std::uint8_t>(10, 39) == 255);
  CHECK(mask.at<std::uint8_t>(52, 10) == 255);
}

TEST_CASE("PartLabeller keeps blobs as parts and sets lines apart") {
  cv::Mat mask(kRows, kCols, CV_8UC1, cv::Scalar(0));
  paint(mask, 10, 29, 10, 29);  // 1 m x 0.8 m
  paint(mask, 0, 79, 60, 62);   // a 4 m line
  paint(mask, 0, 49, 70, 72);   // a 2.5 m stroke: as long as a letter
  const DetectorConfig config;
  PartLabeller labeller(config, config.group_max_part_m, config.region, kRows, kCols);
  DetectorCounters counters;
  REQUIRE(labeller.label(mask, nullptr, counters) == 1);
  const Part& part = labeller.parts()[0];
  CHECK(part.col0 == 10);
  CHECK(part.row0 == 10);
  CHECK(part.col1 == 29);
  CHECK(part.row1 == 29);
  CHECK(part.area == 400);
  CHECK(counters.lane_lines == 2);
  CHECK(counters.parts == 1);
  REQUIRE(labeller.strokes().size() == 1);
  CHECK(labeller.strokes()[0].col0 == 70);
}

TEST_CASE("PartGrouper groups close parts and links candidates across a stroke") {
  const DetectorConfig config;
  const BirdsEyeView view(default_camera_model(), config.region, config.hidden_below);
  const ViewEdges edges(view);
  // No paint in its mask: no candidate touches the view's edge.
  const PaintMask paint_mask(config, config.region, view.rows(), view.cols());
  PartGrouper grouper(config, config, config.region, paint_mask, edges);
  const std::vector<Part> parts = {
      {100, 150, 109, 189, 150, 0, false},  // a letter (too sparse for a stripe)
      {113, 150, 122, 189, 150, 0, false},  // ... and the next, 0.12 m on
      {138, 150, 147, 189, 150, 0, false},  // across a stroke from them
  };
  const std::vector<Part> strokes = {{127, 150, 129, 189, 120, 0, true}};
  std::vector<Candidate> candidates(kMaxCandidates);
  DetectorCounters counters;
  REQUIRE(grouper.group(parts, strokes, candidates, counters) == 2);
  CHECK(candidates[0].parts == 2);
  CHECK(candidates[0].col0 == 100);
  CHECK(candidates[0].col1 == 122);
  CHECK_FALSE(candidates[0].clipped);
  CHECK(candidates[0].across_stroke == 1);
  CHECK(candidates[1].parts == 1);
  CHECK(candidates[1].across_stroke == -1);
  CHECK(counters.candidates == 2);
}
