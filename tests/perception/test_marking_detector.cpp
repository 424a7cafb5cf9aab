#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <span>
#include <string>
#include <vector>

#include <catch2/catch_approx.hpp>
#include <catch2/catch_test_macros.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/persistence.hpp>

#include "app/perception/marking_classes.hpp"
#include "app/perception/marking_classifier.hpp"
#include "app/perception/marking_detector.hpp"
#include "tests/perception/synthetic_road.hpp"

using namespace markloop::perception;
using markloop::perception::testing::clutter_frame;
using markloop::perception::testing::garbage_frame;
using markloop::perception::testing::GroundLine;
using markloop::perception::testing::GroundRect;
using markloop::perception::testing::render_road;
using markloop::perception::testing::render_road_lines;
using markloop::perception::testing::render_road_shaded;
using markloop::perception::testing::render_road_where;

namespace {
const std::string kCameras = std::string(MARKLOOP_SOURCE_DIR) + "/app/cameras/";

// The candidate whose ground centre lies nearest (x, y).
const Candidate* nearest(const MarkingDetector& detector, double x, double y, Detection& where) {
  const Candidate* best = nullptr;
  double best_d = 1e9;
  for (const Candidate& c : detector.candidates()) {
    Detection d{};
    detector.locate(c, d);
    const double dist = std::hypot(d.ground_x - x, d.ground_y - y);
    if (dist < best_d) {
      best_d = dist;
      best = &c;
      where = d;
    }
  }
  return best;
}
// A model that calls every candidate `label`, sure of it: what a test using
// it checks is which candidates are reported.
struct SureModel {
  explicit SureModel(int label) {
    bias[label] = 20.0f;
    model.members = 1;
    model.nets[0] = {kFeatureCount, 1,     kClassifierOutputs, zeros.data(), ones.data(),
                     zeros.data(),  &zero, no_weights.data(),  bias.data()};
  }
  SureModel(const SureModel&) = delete;
  SureModel& operator=(const SureModel&) = delete;

  std::vector<float> zeros = std::vector<float>(kFeatureCount, 0.0f);
  std::vector<float> ones = std::vector<float>(kFeatureCount, 1.0f);
  std::array<float, kClassifierOutputs> bias{}, no_weights{};
  float zero = 0.0f;
  MlpModel model;
};

// A region whose sides the default camera sees from 9 m ahead: the default
// region reaches further to the sides than the camera sees near the car.
DetectorConfig with_sides_in_view(DetectorConfig config) {
  config.region.y_left_m = 6.0f;
  config.region.y_right_m = -6.0f;
  return config;
}

}  // namespace

TEST_CASE("bird's-eye view: pixels map back to the ground points they show") {
  const CameraModel camera = default_camera_model();
  BirdsEyeRegion region;
  const BirdsEyeView view(camera, region);
  CHECK(view.rows() == static_cast<int>(std::lround((region.x_far_m - region.x_near_m) / region.x_step_m)));
  CHECK(view.cols() == static_cast<int>(std::lround((region.y_left_m - region.y_right_m) / region.y_step_m)));
  // A frame whose grey level encodes the image column: the warped value at
  // a bird's-eye pixel must be the column of its ground point's pixel.
  cv::Mat frame(camera.height(), camera.width(), CV_8UC1);
  for (int v = 0; v < frame.rows; ++v)
    for (int u = 0; u < frame.cols; ++u) frame.at<std::uint8_t>(v, u) = static_cast<std::uint8_t>(u / 5);
  cv::Mat out(view.rows(), view.cols(), CV_8UC1);
  view.warp(frame, out);
  int checked = 0;
  for (int r = 0; r < view.rows(); r += 17)
    for (int c = 0; c < view.cols(); c += 13) {
      if (view.valid().at<std::uint8_t>(r, c) == 0) continue;
      Eigen::Vector2d pixel;
      REQUIRE(camera.ground_to_image(
          {view.ground_x(static_cast<float>(r)), view.ground_y(static_cast<float>(c))}, pixel));
      CHECK(std::abs(out.at<std::uint8_t>(r, c) - pixel.x() / 5.0) <= 1.01);
      ++checked;
    }
  CHECK(checked > 100);
}

TEST_CASE("bird's-eye view: nothing is read from below the bonnet's outline") {
  const CameraModel camera = default_camera_model();
  BirdsEyeRegion region;
  const BirdsEyeView open_view(camera, region);
  // A bonnet rising from the image's bottom-left corner to its middle row.
  ImageOutline bonnet;
  const float bottom = static_cast<float>(camera.height() - 1), middle = 0.5f * bottom;
  bonnet.points[0] = {0.0f, bottom};
  bonnet.points[1] = {static_cast<float>(camera.width() - 1), middle};
  bonnet.count = 2;
  const BirdsEyeView view(camera, region, bonnet);
  int hidden = 0, seen = 0;
  for (int r = 0; r < view.rows(); ++r)
    for (int c = 0; c < view.cols(); ++c) {
      if (open_view.valid().at<std::uint8_t>(r, c) == 0) continue;
      Eigen::Vector2d pixel;
      REQUIRE(camera.ground_to_image(
          {view.ground_x(static_cast<float>(r)), view.ground_y(static_cast<float>(c))}, pixel));
      const bool below = pixel.y() >= bonnet.row_at(static_cast<float>(pixel.x()));
      const bool clear = pixel.y() + 2.0 < bonnet.row_at(static_cast<float>(pixel.x()) + 1.0f);
      if (below) CHECK(view.valid().at<std::uint8_t>(r, c) == 0);
      if (clear) CHECK(view.valid().at<std::uint8_t>(r, c) == 255);
      hidden += below ? 1 : 0;
      seen += clear ? 1 : 0;
    }
  CHECK(hidden > 100);
  CHECK(seen > 100);
}

TEST_CASE("bird's-eye view: a row shift reads the image lower; the bonnet moves only when asked") {
  const CameraModel camera = default_camera_model();
  BirdsEyeRegion region;
  ImageOutline bonnet;  // flat, 60 rows above the image's bottom
  const float bonnet_row = static_cast<float>(camera.height() - 60);
  bonnet.points[0] = {0.0f, bonnet_row};
  bonnet.count = 1;
  BirdsEyeView view(camera, region, bonnet);
  // A frame whose grey level encodes the image row.
  cv::Mat frame(camera.height(), camera.width(), CV_8UC1);
  for (int v = 0; v < frame.rows; ++v) frame.row(v).setTo(v / 2);
  cv::Mat out(view.rows(), view.cols(), CV_8UC1);
  constexpr int kShift = 20;
  for (const int outline_shift : {0, kShift}) {
    view.set_row_shift(kShift, outline_shift);
    CHECK(view.row_shift() == kShift);
    view.warp(frame, out);
    const double outline = static_cast<double>(bonnet_row) + outline_shift;
    int checked = 0, hidden = 0, below_fixed_outline = 0;
    for (int r = 0; r < view.rows(); ++r)
      for (int c = 0; c < view.cols(); ++c) {
        Eigen::Vector2d pixel;
        if (!camera.ground_to_image(
                {view.ground_x(static_cast<float>(r)), view.ground_y(static_cast<float>(c))}, pixel))
          continue;
        const double read_row = pixel.y() + kShift;
        if (view.valid().at<std::uint8_t>(r, c) == 0) {
          hidden += read_row + 1.0 >= outline ? 1 : 0;
          continue;
        }
        // Nothing read at or below the outline (moved or not) ...
        CHECK(read_row + 1.0 < outline);
        // ... and what is read lies kShift rows below the calibration's pixel.
        CHECK(std::abs(out.at<std::uint8_t>(r, c) - read_row / 2.0) <= 1.01);
        below_fixed_outline += read_row + 1.0 >= bonnet_row ? 1 : 0;
        ++checked;
      }
    CHECK(checked > 1000);
    CHECK(hidden > 100);
    // The moved outline uncovers the rows it left.
    if (outline_shift == 0)
      CHECK(below_fixed_outline == 0);
    else
      CHECK(below_fixed_outline > 100);
  }
  // Back to the calibration: as built.
  view.set_row_shift(0, 0);
  const BirdsEyeView fresh(camera, region, bonnet);
  CHECK(cv::countNonZero(view.valid() != fresh.valid()) == 0);
}

TEST_CASE("detector: a painted block is found where it lies on the road") {
  const CameraModel camera = default_camera_model();
  MarkingDetector detector(camera);
  // A legend-sized block (2.4 m x 0.6 m) at 10 m, 1.5 m left.
  const cv::Mat frame = render_road(camera, {{8.8, 11.2, 1.2, 1.8}});
  detector.detect(frame);
  REQUIRE_FALSE(detector.candidates().empty());
  Detection where{};
  const Candidate* c = nearest(detector, 10.0, 1.5, where);
  REQUIRE(c != nullptr);
  CHECK(where.ground_x == Catch::Approx(10.0).margin(0.15));
  CHECK(where.ground_y == Catch::Approx(1.5).margin(0.08));
  CHECK(c->length_m == Catch::Approx(2.4).margin(0.2));
  CHECK(c->width_m == Catch::Approx(0.6).margin(0.1));
  // The quad is the block's outline in the image.
  Eigen::Vector2d near_left;
  REQUIRE(camera.ground_to_image({8.8, 1.8}, near_left));
  CHECK(where.quad[0][0] == Catch::Approx(near_left.x()).margin(4.0));
  CHECK(where.quad[0][1] == Catch::Approx(near_left.y()).margin(4.0));
}

TEST_CASE("detector: digits side by side are grouped, separate markings are not") {
  const CameraModel camera = default_camera_model();
  MarkingDetector detector(camera);
  // Two 'digits' 0.3 m apart (one marking) and a block 3 m to the right.
  const cv::Mat frame =
      render_road(camera, {{9.0, 11.4, 0.9, 1.4}, {9.0, 11.4, 0.3, 0.6}, {9.0, 11.4, -2.9, -2.3}});
  detector.detect(frame);
  Detection where{};
  const Candidate* pair = nearest(detector, 10.2, 0.85, where);
  REQUIRE(pair != nullptr);
  CHECK(pair->parts == 2);
  CHECK(where.ground_y == Catch::Approx(0.85).margin(0.08));
  const Candidate* single = nearest(detector, 10.2, -2.6, where);
  REQUIRE(single != nullptr);
  CHECK(single->parts == 1);
}

TEST_CASE("detector: lane lines are set apart, not classified") {
  const CameraModel camera = default_camera_model();
  MarkingDetector detector(camera);
  const cv::Mat frame = render_road(camera, {{3.0, 25.0, 1.7, 1.85}, {3.0, 25.0, -1.85, -1.7}});
  detector.detect(frame);
  CHECK(detector.counters().lane_lines >= 2);
  CHECK(detector.candidates().empty());
}

TEST_CASE("detector: a worn stop line meeting a lane line comes apart from it") {
  const CameraModel camera = default_camera_model();
  MarkingDetector detector(camera);
  // The lane's left line, and a stop line 0.45 m along by 3.3 m across
  // touching it at 10 m. Only its far 0.15 m runs unbroken across; its
  // near 0.25 m is worn into 0.4 m pieces with 0.12 m gaps, the first one
  // touching the line: rows too broken to be cut themselves.
  std::vector<GroundRect> paint{{3.0, 25.0, 1.7, 1.85}, {10.3, 10.45, -1.6, 1.7}};
  for (double y1 = 1.7; y1 > -1.6; y1 -= 0.52)  // from the line rightwards
    paint.push_back({10.05, 10.3, std::max(-1.6, y1 - 0.4), y1});
  detector.detect(render_road(camera, paint));
  CHECK(detector.counters().lane_lines >= 1);
  Detection where{};
  const Candidate* bar = nearest(detector, 10.25, 0.05, where);
  REQUIRE(bar != nullptr);
  CHECK(where.ground_x == Catch::Approx(10.25).margin(0.15));
  CHECK(where.ground_y == Catch::Approx(0.05).margin(0.15));
  CHECK(bar->length_m < 0.8);  // the bar alone, no piece of the line
  CHECK(bar->width_m == Catch::Approx(3.3).margin(0.25));
}

TEST_CASE("detector: a stop line worn through every row comes apart from the lane line it meets") {
  const CameraModel camera = default_camera_model();
  // The lane's left line, and a stop line 0.45 m along by 3.3 m across
  // touching it at 10 m, worn through its whole length into 0.3 m pieces
  // 0.1 m apart (three quarters paint): no row runs unbroken for the
  // 1.5 m the cut looks for.
  std::vector<GroundRect> paint{{3.0, 25.0, 1.7, 1.85}};
  for (double y1 = 1.7; y1 > -1.6; y1 -= 0.4)  // from the line rightwards
    paint.push_back({10.0, 10.45, std::max(-1.6, y1 - 0.3), y1});
  const cv::Mat frame = render_road(camera, paint);
  const auto bar_alone = [&](const DetectorConfig& config) {
    MarkingDetector detector(camera, config);
    detector.detect(frame);
    Detection where{};
    const Candidate* bar = nearest(detector, 10.25, 0.05, where);
    return bar != nullptr && bar->length_m < 0.8 && std::abs(bar->width_m - 3.3) < 0.3 &&
           std::abs(where.ground_y - 0.05) < 0.15;
  };
  DetectorConfig unbroken_runs_only;
  unbroken_runs_only.junction_min_fill = 0.0f;
  CHECK_FALSE(bar_alone(unbroken_runs_only));  // joined to the line: set apart with it
  CHECK(bar_alone(DetectorConfig{}));
}

TEST_CASE("detector: a crosswalk's stripes are one candidate; two words side by side stay two") {
  const CameraModel camera = default_camera_model();
  // Six stripes 3 m along and 0.5 m wide, 0.5 m apart: further apart than
  // the letters of a word are grouped.
  std::vector<GroundRect> stripes;
  for (double y = -3.0; y < 2.9; y += 1.0) stripes.push_back({9.0, 12.0, y, y + 0.5});
  MarkingDetector crosswalk(camera);
  crosswalk.detect(render_road(camera, stripes));
  REQUIRE(crosswalk.candidates().size() == 1);
  CHECK(crosswalk.candidates()[0].parts == 6);
  CHECK(crosswalk.candidates()[0].width_m == Catch::Approx(5.5).margin(0.25));

  // Two words in neighbouring lanes, 0.7 m apart: letters 2.4 m along and
  // 0.6 m across, outlines 0.15 m wide (a letter's strokes fill about half
  // its box), 0.1 m apart within a word.
  std::vector<GroundRect> letters;
  for (const double first : {-2.3, 0.4})
    for (int k = 0; k < 3; ++k) {
      const double y0 = first + 0.7 * k, y1 = y0 + 0.6;
      letters.push_back({9.0, 9.15, y0, y1});
      letters.push_back({11.25, 11.4, y0, y1});
      letters.push_back({9.0, 11.4, y0, y0 + 0.15});
      letters.push_back({9.0, 11.4, y1 - 0.15, y1});
    }
  MarkingDetector words(camera);
  words.detect(render_road(camera, letters));
  REQUIRE(words.candidates().size() == 2);
  for (const Candidate& word : words.candidates()) {
    CHECK(word.parts == 3);
    CHECK(word.width_m == Catch::Approx(2.0).margin(0.25));
  }
}

TEST_CASE("detector: a word split by its I, set apart as a line, is one detection; not across a lane dash") {
  const CameraModel camera = default_camera_model();
  const int xing = static_cast<int>(*marking_class_from_name("xing"));
  const SureModel sure(xing);
  DetectorConfig config = with_sides_in_view({});
  config.model = &sure.model;
  config.cnn_share = 0.0f;  // the sure model alone
  // A letter: an outline 2.4 m along and 0.6 m across, strokes 0.15 m wide.
  const auto letter = [](std::vector<GroundRect>& paint, double x0, double x1, double y0) {
    const double y1 = y0 + 0.6;
    paint.push_back({x0, x0 + 0.15, y0, y1});
    paint.push_back({x1 - 0.15, x1, y0, y1});
    paint.push_back({x0, x1, y0, y0 + 0.15});
    paint.push_back({x0, x1, y1 - 0.15, y1});
  };
  // X, I, N, G: the I a bar 0.15 m wide, as thin as a line, 0.25 m from the
  // letters either side, which are further apart than letters group.
  std::vector<GroundRect> word;
  letter(word, 9.0, 11.4, -1.5);
  word.push_back({9.0, 11.4, -0.65, -0.5});
  letter(word, 9.0, 11.4, -0.25);
  letter(word, 9.0, 11.4, 0.45);
  MarkingDetector detector(camera, config);
  const auto found = detector.detect(render_road(camera, word));
  CHECK(detector.candidates().size() == 2);  // X, and N G
  CHECK(detector.counters().candidates == 2);
  CHECK(detector.counters().joined == 1);
  REQUIRE(found.size() == 1);
  CHECK(found[0].ground_y == Catch::Approx(-0.225).margin(0.08));  // the word's middle
  CHECK(found[0].ground_x == Catch::Approx(10.2).margin(0.15));

  // The same word with its X run out of the view's right side: the N G
  // beside it is no word of its own, but the word seen in part. The X cut
  // to its upright is a sliver as thin as a line, set apart as one; cut less,
  // a candidate cut by the edge.
  const double view_right = config.region.y_right_m - config.guard_m;
  for (const double x_seen_m : {0.3, 0.45}) {
    CAPTURE(x_seen_m);
    std::vector<GroundRect> cut_word = word;
    const double shift = view_right + x_seen_m - (-1.5 + 0.6);  // the X's left side there
    for (GroundRect& paint : cut_word) {
      paint.y0 += shift;
      paint.y1 += shift;
    }
    MarkingDetector cut(camera, config);
    CHECK(cut.detect(render_road(camera, cut_word)).empty());
    REQUIRE(cut.candidates().size() == (x_seen_m < 0.4 ? 1u : 2u));
    for (const Candidate& part : cut.candidates()) CHECK(part.clipped);
    CHECK(cut.counters().clipped == 1);  // the first part reports the word
  }

  // Letters of two words either side of a lane dash 3 m long, as close: the
  // dash is longer than the letters, so no letter of theirs.
  std::vector<GroundRect> two_words;
  letter(two_words, 9.3, 11.7, -0.925);
  two_words.push_back({9.0, 12.0, -0.075, 0.075});
  letter(two_words, 9.3, 11.7, 0.325);
  MarkingDetector apart(camera, config);
  CHECK(apart.detect(render_road(camera, two_words)).size() == 2);
  CHECK(apart.counters().joined == 0);
}

namespace {

// A candidate of columns col0..col1 in rows 100..179 (a letter 2.4 m long),
// classified `label`, linked across no stroke yet.
Candidate stroke_candidate(int col0, int col1, int label, float score, bool clipped, bool near_only) {
  Candidate c{};
  c.col0 = col0;
  c.col1 = col1;
  c.row0 = 100;
  c.row1 = 179;
  c.parts = 1;
  c.length_m = 2.4f;
  c.width_m = 0.03f * static_cast<float>(col1 - col0 + 1);
  c.predicted = label;
  c.score = score;
  c.clipped = clipped;
  c.clipped_near_only = near_only;
  c.across_stroke = -1;
  return c;
}

}  // namespace

TEST_CASE("detector: candidates across a stroke join only when classified alike") {
  const int xing = static_cast<int>(*marking_class_from_name("xing"));
  const int stop = static_cast<int>(*marking_class_from_name("stop"));
  std::array<std::int32_t, 4> reported_by{};
  std::vector<Candidate> word = {stroke_candidate(10, 30, xing, 0.7f, false, false),
                                 stroke_candidate(40, 80, xing, 0.9f, true, true)};
  word[0].across_stroke = 1;
  CHECK(join_across_strokes(word, reported_by) == 1);
  CHECK(reported_by[0] == 0);
  CHECK(reported_by[1] == 0);
  const Candidate whole = joined_candidate(word, reported_by, 0);
  CHECK(whole.col0 == 10);
  CHECK(whole.col1 == 80);
  CHECK(whole.width_m == Catch::Approx(0.03f * 71.0f));
  CHECK(whole.parts == 2);
  CHECK(whole.score == 0.9f);
  CHECK(whole.clipped);
  CHECK(whole.clipped_near_only);
  CHECK(word[0].col1 == 30);  // the candidates stay as classified

  word[1].predicted = stop;
  CHECK(join_across_strokes(word, reported_by) == 0);
  CHECK(reported_by[1] == 1);
}

TEST_CASE("detector: a broken letter between a word's candidates joins the word, up to two pieces") {
  const int xing = static_cast<int>(*marking_class_from_name("xing"));
  // A letter broken by a shadow, its pieces rejected (or the diagonal of
  // an N between its upright and the I, taken for a railway mark), between
  // two of the word's candidates: part of the word, up to two of them.
  const int rail = static_cast<int>(*marking_class_from_name("rail"));
  for (const int pieces : {1, 2, 3}) {
    std::vector<Candidate> broken = {stroke_candidate(10, 30, xing, 0.8f, false, false)};
    for (int k = 0; k < pieces; ++k)
      broken.push_back(
          stroke_candidate(40 + 10 * k, 45 + 10 * k, k == 0 ? rail : kRejectClass, 0.95f, false, false));
    broken.push_back(stroke_candidate(80, 100, xing, 0.7f, false, false));
    for (std::size_t k = 0; k + 1 < broken.size(); ++k) broken[k].across_stroke = static_cast<int>(k + 1);
    std::array<std::int32_t, 5> by{};
    CHECK(join_across_strokes(broken, by) == (pieces <= 2 ? 1u : 0u));
    if (pieces > 2) continue;
    for (std::size_t k = 0; k < broken.size(); ++k) CHECK(by[k] == 0);
    const Candidate joined = joined_candidate(broken, by, 0);
    CHECK(joined.col1 == 100);
    CHECK(joined.score == 0.8f);  // the word's, not the pieces' scores
    CHECK(joined.predicted == xing);
  }
}

TEST_CASE("detector: a chain of candidates across strokes joins in either order") {
  const int xing = static_cast<int>(*marking_class_from_name("xing"));
  std::array<std::int32_t, 4> reported_by{};
  // A chain, the candidates in either order: each links to the next.
  for (const bool reversed : {false, true}) {
    std::vector<Candidate> chain = {stroke_candidate(10, 30, xing, 0.8f, false, false),
                                    stroke_candidate(40, 60, xing, 0.8f, false, false),
                                    stroke_candidate(70, 90, xing, 0.8f, true, false)};
    if (reversed) std::swap(chain[0], chain[2]);
    const int a = reversed ? 2 : 0, c = reversed ? 0 : 2;
    chain[static_cast<std::size_t>(a)].across_stroke = 1;
    chain[1].across_stroke = c;
    CHECK(join_across_strokes(chain, reported_by) == 2);
    CHECK(reported_by[0] == a);
    CHECK(reported_by[1] == a);
    CHECK(reported_by[2] == a);
    const Candidate joined = joined_candidate(chain, reported_by, static_cast<std::size_t>(a));
    CHECK(joined.col0 == 10);
    CHECK(joined.col1 == 90);
    CHECK(joined.clipped);
    CHECK_FALSE(joined.clipped_near_only);  // the third is cut by another edge
  }
}

TEST_CASE("detector: a word's letters a little further apart than the grouping gap are one detection") {
  const int xing = static_cast<int>(*marking_class_from_name("xing"));
  const int stop = static_cast<int>(*marking_class_from_name("stop"));
  const int forward = static_cast<int>(*marking_class_from_name("forward"));
  const auto candidate = [](int col0, int col1, int row0, int label, bool clipped) {
    Candidate c{};
    c.col0 = col0;
    c.col1 = col1;
    c.row0 = row0;
    c.row1 = row0 + 47;
    c.parts = 1;
    c.length_m = 2.4f;
    c.predicted = label;
    c.score = 0.9f;
    c.clipped = clipped;
    c.across_stroke = -1;
    return c;
  };
  const int gap = 15, max_cols = 80;  // 0.6 m and 3.2 m at 0.04 m a column
  SECTION("XIN and G; a third letter through the second") {
    const std::vector<Candidate> word = {candidate(160, 170, 101, xing, false),
                                         candidate(100, 130, 100, xing, false),
                                         candidate(140, 150, 102, xing, false)};
    std::array<std::int32_t, 3> by{0, 1, 2};
    CHECK(join_split_words(word, by, gap, max_cols, 0.85f) == 2);
    CHECK(by == std::array<std::int32_t, 3>{0, 0, 0});
    const Candidate whole = joined_candidate(word, by, 0);
    CHECK(whole.col0 == 100);
    CHECK(whole.col1 == 170);
  }
  SECTION("not: too wide together, another class, no word, cut, along the road, too far") {
    const std::vector<Candidate> apart = {candidate(100, 160, 100, stop, false),
                                          candidate(170, 230, 100, stop, false),  // the next lane's STOP
                                          candidate(240, 260, 100, xing, false),  // another word
                                          candidate(300, 320, 100, forward, false),
                                          candidate(330, 350, 100, forward, false),  // arrows
                                          candidate(400, 420, 100, xing, false),
                                          candidate(430, 450, 100, xing, true),  // the second cut
                                          candidate(500, 520, 100, xing, false),
                                          candidate(530, 550, 130, xing, false),  // half along
                                          candidate(600, 620, 100, xing, false),
                                          candidate(640, 660, 100, xing, false)};  // 19 apart
    std::array<std::int32_t, 11> by{};
    for (std::size_t i = 0; i < by.size(); ++i) by[i] = static_cast<std::int32_t>(i);
    CHECK(join_split_words(apart, by, gap, max_cols, 0.85f) == 0);
  }
  SECTION("not: a candidate already in a word across its I") {
    const std::vector<Candidate> words = {candidate(100, 130, 100, xing, false),
                                          candidate(140, 170, 100, xing, false),
                                          candidate(180, 190, 100, xing, false)};
    std::array<std::int32_t, 3> by{0, 0, 2};  // the first two joined across a stroke
    CHECK(join_split_words(words, by, gap, max_cols, 0.85f) == 0);
    CHECK(by[2] == 2);
  }
}

TEST_CASE("detector: sunlit road beside a shadow is not paint; an arrow's solid head still is") {
  const CameraModel camera = default_camera_model();
  // An arrow: a 0.3 m shaft 3 m long under a solid 1.2 m x 1.5 m head
  // (a quadrant of the threshold's window lies wholly inside it).
  const std::vector<GroundRect> arrow{{8.0, 11.0, -0.15, 0.15}, {11.0, 12.5, -0.6, 0.6}};
  const auto on_arrow = [&](const Eigen::Vector2d& g) {
    return std::any_of(arrow.begin(), arrow.end(), [&](const GroundRect& r) { return r.covers(g); });
  };
  // A tree's round shadow to the left and a building's to the right, its
  // edge slanting across the road; the shadowed road is 45 % as bright.
  const auto in_shadow = [](const Eigen::Vector2d& g) {
    return std::hypot(g.x() - 10.0, g.y() - 3.0) < 1.5 || g.y() < -2.0 + 0.4 * (g.x() - 10.0);
  };
  const cv::Mat frame = render_road_shaded(camera, on_arrow, in_shadow, 130, 230, 0.45);
  // Paint pixels more than 0.2 m from the arrow: the sunlit rims.
  const auto paint_off_and_on_arrow = [&](const MarkingDetector& detector) {
    const BirdsEyeView& view = detector.birdseye();
    const cv::Mat& mask = detector.paint_mask();
    std::array<int, 2> counts{};
    for (int r = 0; r < mask.rows; ++r)
      for (int c = 0; c < mask.cols; ++c) {
        if (mask.at<std::uint8_t>(r, c) == 0) continue;
        const Eigen::Vector2d g(view.ground_x(static_cast<float>(r)), view.ground_y(static_cast<float>(c)));
        const bool near_arrow = std::any_of(arrow.begin(), arrow.end(), [&](const GroundRect& a) {
          return GroundRect{a.x0 - 0.2, a.x1 + 0.2, a.y0 - 0.2, a.y1 + 0.2}.covers(g);
        });
        ++counts[near_arrow ? 1 : 0];
      }
    return counts;
  };

  DetectorConfig window_only;
  window_only.quadrant_min_contrast = 0;
  MarkingDetector before(camera, window_only);
  before.detect(frame);
  const auto [rims_before, arrow_before] = paint_off_and_on_arrow(before);
  CHECK(rims_before > 1000);  // the window's test alone: the rims are paint

  MarkingDetector detector(camera);
  detector.detect(frame);
  const auto [rims, arrow_paint] = paint_off_and_on_arrow(detector);
  CHECK(rims == 0);
  // The head is not eaten away (against each quadrant's whole mean, paint
  // included, half of the arrow's paint went).
  CHECK(arrow_paint >= 0.97 * arrow_before);
  REQUIRE(detector.candidates().size() == 1);
  const Candidate& found = detector.candidates()[0];
  CHECK(found.length_m == Catch::Approx(4.5).margin(0.2));
  CHECK(found.width_m == Catch::Approx(1.2).margin(0.1));
}

TEST_CASE("detector: a short line at an angle to the road is set apart, and groups with nothing") {
  const CameraModel camera = default_camera_model();
  MarkingDetector detector(camera);
  // 3 m of lane line at 30 degrees to the road (a bend, a road crossed at an
  // angle): its box, 2.6 m x 1.5 m, is neither thin nor sparse. A digit
  // 0.25 m beside it would be grouped with it, were it a part.
  const GroundLine oblique{8.0, 1.5, 10.6, 0.0};
  const GroundRect digit{8.6, 9.8, -0.5, -0.1};
  detector.detect(render_road_lines(camera, {oblique}, {digit}));
  CHECK(detector.counters().lane_lines == 1);
  REQUIRE(detector.candidates().size() == 1);
  const Candidate& c = detector.candidates()[0];
  CHECK(c.parts == 1);
  CHECK(c.width_m == Catch::Approx(0.4).margin(0.1));
  CHECK(c.length_m == Catch::Approx(1.2).margin(0.15));
}

TEST_CASE("detector: a closed outline is a candidate; the same lines left open are set apart") {
  const CameraModel camera = default_camera_model();
  // A diamond 5 m long and 1.2 m wide at 40 degrees to the road: its box
  // (3.8 m x 3.2 m) is sparse, as a line's across a bend is.
  const double along = 2.5, half_width = 0.6, angle = 40.0 * std::numbers::pi / 180.0;
  const Eigen::Vector2d centre(11.0, 0.0), u(std::cos(angle), std::sin(angle)), n(-u.y(), u.x());
  const std::array<Eigen::Vector2d, 4> corner = {centre + along * u, centre + half_width * n,
                                                 centre - along * u, centre - half_width * n};
  std::vector<GroundLine> sides;
  for (std::size_t i = 0; i < 4; ++i) {
    const Eigen::Vector2d& a = corner[i];
    const Eigen::Vector2d& b = corner[(i + 1) % 4];
    sides.push_back({a.x(), a.y(), b.x(), b.y()});
  }
  MarkingDetector closed(camera);
  closed.detect(render_road_lines(camera, sides));
  REQUIRE(closed.candidates().size() == 1);
  CHECK(closed.counters().lane_lines == 0);
  CHECK(closed.candidates()[0].length_m == Catch::Approx(3.8).margin(0.3));
  CHECK(closed.candidates()[0].width_m == Catch::Approx(3.2).margin(0.3));

  sides.pop_back();
  MarkingDetector open(camera);
  open.detect(render_road_lines(camera, sides));
  CHECK(open.counters().lane_lines == 1);
  CHECK(open.candidates().empty());
}

TEST_CASE("detector: a piece inside a larger marking is no detection of its own") {
  const auto box = [](int col0, int row0, int col1, int row1, int label, bool clipped = false) {
    Candidate c{};
    c.col0 = col0;
    c.row0 = row0;
    c.col1 = col1;
    c.row1 = row1;
    c.predicted = label;
    c.clipped = clipped;
    return c;
  };
  const int rail = static_cast<int>(*marking_class_from_name("rail"));
  const int xing = static_cast<int>(*marking_class_from_name("xing"));
  const std::vector<Candidate> candidates = {
      box(100, 10, 190, 90, rail),                  // 0: an X
      box(110, 40, 125, 60, rail),                  // 1: an R inside it
      box(170, 40, 195, 60, rail),                  // 2: 21 of its 26 columns inside it
      box(120, 20, 140, 30, xing),                  // 3: inside, another class
      box(100, 10, 190, 90, rail),                  // 4: the same box again (not larger)
      box(300, 200, 390, 300, kRejectClass, true),  // 5: an X cut by the view's edge, rejected
      box(310, 240, 325, 260, rail),                // 6: its R
      box(300, 100, 390, 190, kRejectClass),        // 7: something rejected, whole
      box(310, 140, 325, 160, rail),                // 8: a marking inside its box
      box(180, 40, 205, 60, rail),                  // 9: 11 of its 26 columns inside the X
  };
  CHECK_FALSE(is_piece_of_larger(candidates, 0));
  CHECK(is_piece_of_larger(candidates, 1));
  CHECK(is_piece_of_larger(candidates, 2));  // an R reaching a little past the X
  CHECK_FALSE(is_piece_of_larger(candidates, 3));
  CHECK_FALSE(is_piece_of_larger(candidates, 4));
  CHECK(is_piece_of_larger(candidates, 6));
  CHECK_FALSE(is_piece_of_larger(candidates, 8));
  CHECK_FALSE(is_piece_of_larger(candidates, 9));
}

TEST_CASE("detector: a still reports a marking cut by the near edge, marked partial; a stream does not") {
  const CameraModel camera = default_camera_model();
  const int forward = static_cast<int>(*marking_class_from_name("forward"));
  const SureModel sure(forward);
  REQUIRE(model_is_usable(sure.model));
  DetectorConfig config;
  config.model = &sure.model;
  config.cnn_share = 0.0f;  // the sure model alone
  MarkingDetector detector(camera, config);
  const double near = config.region.x_near_m, far = config.region.x_far_m;
  const double left = config.region.y_left_m;
  const std::vector<GroundRect> blocks = {
      {near - 1.0, near + 1.4, 0.3, 0.9},    // across the near edge
      {far - 1.2, far + 1.2, -0.9, -0.3},    // across the far edge
      {14.0, 16.4, left - 0.5, left + 0.5},  // across the left edge
      {9.0, 11.4, -2.9, -2.3},               // whole
  };
  const cv::Mat frame = render_road(camera, blocks);
  const auto reported = [&](std::span<const Detection> detections, const GroundRect& block) {
    const Detection* found = nullptr;
    for (const Detection& d : detections)
      if (d.ground_x >= block.x0 && d.ground_x <= block.x1 && d.ground_y >= block.y0 &&
          d.ground_y <= block.y1)
        found = &d;
    return found;
  };

  const auto stream = detector.detect(frame);
  REQUIRE(reported(stream, blocks[3]) != nullptr);
  CHECK_FALSE(reported(stream, blocks[3])->partial);
  for (int i = 0; i < 3; ++i) CHECK(reported(stream, blocks[i]) == nullptr);
  CHECK(detector.counters().clipped == 3);

  const auto still = detector.detect_still(frame);
  const Detection* cut = reported(still, blocks[0]);
  REQUIRE(cut != nullptr);
  CHECK(cut->partial);
  CHECK(cut->label == forward);
  // Its centre is the visible part's: between the edge and the block's far end.
  CHECK(cut->ground_x == Catch::Approx(0.5 * (near + blocks[0].x1)).margin(0.15));
  CHECK(reported(still, blocks[1]) == nullptr);
  CHECK(reported(still, blocks[2]) == nullptr);
  REQUIRE(reported(still, blocks[3]) != nullptr);
  CHECK_FALSE(reported(still, blocks[3])->partial);
  CHECK(detector.counters().partial == 1);
  CHECK(detector.counters().clipped == 3 + 2);

  config.report_partial_in_stills = false;
  MarkingDetector whole_only(camera, config);
  CHECK(reported(whole_only.detect_still(frame), blocks[0]) == nullptr);
}

TEST_CASE("detector: the guard band shows a marking ending at the region's edge whole") {
  const CameraModel camera = default_camera_model();
  const SureModel sure(static_cast<int>(*marking_class_from_name("forward")));
  DetectorConfig config = with_sides_in_view({});
  config.model = &sure.model;
  config.cnn_share = 0.0f;  // the sure model alone
  const double far = config.region.x_far_m, left = config.region.y_left_m;
  const std::vector<GroundRect> blocks = {
      {far - 2.42, far - 0.02, -0.9, -0.3},   // ends 2 cm inside the far end
      {9.0, 11.4, left - 0.62, left - 0.02},  // ends 2 cm inside the left side
      {13.0, 14.0, left + 0.06, left + 0.2},  // wholly beyond the left side
  };
  const cv::Mat frame = render_road(camera, blocks);
  const auto reported = [](std::span<const Detection> detections, const GroundRect& block) {
    for (const Detection& d : detections)
      if (d.ground_x >= block.x0 && d.ground_x <= block.x1 && d.ground_y >= block.y0 &&
          d.ground_y <= block.y1)
        return true;
    return false;
  };

  // Without the band, the paint's last pixels lie on the view's edge: cut.
  config.guard_m = 0.0f;
  MarkingDetector unguarded(camera, config);
  const auto without = unguarded.detect(frame);
  CHECK_FALSE(reported(without, blocks[0]));
  CHECK_FALSE(reported(without, blocks[1]));
  CHECK(unguarded.counters().clipped == 2);

  config.guard_m = 0.3f;
  MarkingDetector guarded(camera, config);
  const auto with = guarded.detect(frame);
  CHECK(reported(with, blocks[0]));
  CHECK(reported(with, blocks[1]));
  CHECK_FALSE(reported(with, blocks[2]));
  CHECK(guarded.counters().clipped == 0);
  CHECK(guarded.counters().beyond_region == 1);
  // The band is whole pixels wide: the pixels over the region are the same.
  CHECK(guarded.birdseye().rows() == unguarded.birdseye().rows() + 6);
  CHECK(guarded.birdseye().cols() == unguarded.birdseye().cols() + 2 * 8);
}

TEST_CASE("detector: a lane dash coming into view does not make a marking look cut") {
  const CameraModel camera = default_camera_model();
  const SureModel sure(static_cast<int>(*marking_class_from_name("stop")));
  DetectorConfig config = with_sides_in_view({});
  config.model = &sure.model;
  config.cnn_share = 0.0f;  // the sure model alone
  cv::Mat frame;
  double word_x = 0.0, word_y = 0.0;  // the word's centre on the ground
  SECTION("at the far end") {
    const double far = config.region.x_far_m;
    // A word ending 0.4 m short of the far end, and beside it, 0.2 m to the
    // side and 0.2 m beyond it, a dash running on out of the view: within the
    // grouping gaps, and too short in view to be set apart as a line.
    const GroundRect word{far - 1.6, far - 0.4, -0.9, -0.1};
    const GroundRect dash{far - 0.2, far + 3.0, 0.1, 0.25};
    frame = render_road(camera, {word, dash});
    word_x = far - 1.0;
    word_y = -0.5;
  }
  SECTION("at an angle, out of the side") {
    const double left = config.region.y_left_m;
    // A word 0.6 m inside the left side, and beside it a dash at 45 degrees
    // (a bend) running out of the view's side: its box in view is about
    // 0.75 m wide, wider than a line's, but it is as thin as one along its
    // own axis.
    const GroundRect word{9.0, 10.2, left - 1.4, left - 0.6};
    const GroundLine dash{9.3, left - 0.45, 12.0, left + 2.25, 0.15};
    frame =
        render_road_where(camera, [&](const Eigen::Vector2d& g) { return word.covers(g) || dash.covers(g); });
    word_x = 9.6;
    word_y = left - 1.0;
  }
  MarkingDetector detector(camera, config);
  const auto detections = detector.detect(frame);
  REQUIRE(detections.size() == 1);
  CHECK(detections[0].ground_x == Catch::Approx(word_x).margin(0.15));
  CHECK(detections[0].ground_y == Catch::Approx(word_y).margin(0.1));
  CHECK(detector.counters().clipped == 1);  // the dash, alone
}

TEST_CASE("detector: an empty road gives nothing; wrong frames are counted, not processed") {
  const CameraModel camera = default_camera_model();
  MarkingDetector detector(camera);
  CHECK(detector.detect(render_road(camera, {})).empty());
  CHECK(detector.candidates().empty());
  CHECK(detector.counters().frames == 1);

  const cv::Mat small(100, 100, CV_8UC1, cv::Scalar(0));
  CHECK(detector.detect(small).empty());
  const cv::Mat colour(camera.height(), camera.width(), CV_8UC3, cv::Scalar(0, 0, 0));
  CHECK(detector.detect(colour).empty());
  CHECK(detector.counters().bad_frames == 2);
  CHECK(detector.counters().frames == 3);
}

TEST_CASE("detector: frames of noise and checkerboards are taken for noise and not searched") {
  const CameraModel camera = default_camera_model();
  MarkingDetector detector(camera);
  for (int k = 0; k < 20; ++k) {
    CHECK(detector.detect(garbage_frame(camera, k)).empty());
    CHECK(detector.last_view() == ViewKind::Noisy);
    CHECK(detector.candidates().empty());
    CHECK(detector.lane_segments().empty());
    CHECK(cv::countNonZero(detector.paint_mask()) == 0);
  }
  const DetectorCounters& counters = detector.counters();
  CHECK(counters.frames == 20);
  CHECK(counters.bad_frames == 0);  // the right size and type: looked at, and judged
  CHECK(counters.noisy_frames == 20);
  CHECK(counters.candidates == 0);
}

TEST_CASE("detector: paint everywhere overflows the cap, is counted, and reports nothing") {
  const CameraModel camera = default_camera_model();
  MarkingDetector detector(camera);
  std::uint64_t cluttered = 0, withheld = 0;
  for (int k = 0; k < 20; ++k) {
    const DetectorCounters before = detector.counters();
    const std::size_t found = detector.detect(clutter_frame(camera, k)).size();
    CHECK(detector.candidates().size() <= kMaxCandidates);
    const DetectorCounters& after = detector.counters();
    const bool overflowed =
        after.candidates_dropped + after.parts_dropped > before.candidates_dropped + before.parts_dropped;
    CHECK(detector.last_view() == (overflowed ? ViewKind::Cluttered : ViewKind::Road));
    if (overflowed) {
      CHECK(found == 0);
      ++cluttered;
      withheld += after.detections_withheld - before.detections_withheld;
    }
    CHECK(after.detections - before.detections == found);
  }
  CHECK(cluttered > 0);
  CHECK(withheld > 0);  // rows of tiles pass for crosswalks
  CHECK(detector.counters().cluttered_frames == cluttered);
}

TEST_CASE("detector: a view that shows no road is told apart: flat, noisy, cluttered, unusable") {
  const CameraModel camera = default_camera_model();
  MarkingDetector detector(camera);
  // Bare asphalt (+-6 grey levels of texture) without a line, a verge or
  // light falling off: nothing a block's mean would show (real roads' views
  // measured 11 levels and more).
  detector.detect(render_road(camera, {}));
  CHECK(detector.last_view() == ViewKind::Flat);
  CHECK(detector.last_view_spread().blocks < 0.5f);  // 0.36
  const cv::Mat road = render_road(camera, {{3.0, 25.0, 1.7, 1.85}, {3.0, 25.0, -1.85, -1.7}});
  detector.detect(road);
  CHECK(detector.last_view() == ViewKind::Road);
  // A covered lens or darkness (black with a sensor's noise), a stuck sensor
  // (mid-grey), an overexposed one (white).
  cv::Mat frame(camera.height(), camera.width(), CV_8UC1);
  cv::RNG rng(7);
  for (const int grey : {0, 128, 255}) {
    rng.fill(frame, cv::RNG::NORMAL, grey, 1.0);
    CHECK(detector.detect(frame).empty());
    CHECK(detector.last_view() == ViewKind::Flat);
    CHECK(detector.last_view_spread().blocks < 1.0f);
  }
  // The lens covered, the sensor's gain up: dark noise of 4 to 32 levels.
  for (const double sigma : {4.0, 8.0, 16.0, 32.0}) {
    rng.fill(frame, cv::RNG::NORMAL, 4.0, sigma);
    CHECK(detector.detect(frame).empty());
    CHECK(detector.last_view() == (sigma < 10.0 ? ViewKind::Flat : ViewKind::Noisy));
  }
  // Uniform noise: its blocks hardly vary against its pixels.
  rng.fill(frame, cv::RNG::UNIFORM, 0, 256);
  detector.detect(frame);
  CHECK(detector.last_view() == ViewKind::Noisy);
  CHECK(detector.last_view_spread().blocks < 0.25f * detector.last_view_spread().pixels);
  // The road under a sensor's noise of 6 grey levels (the simulator's night)
  // is still a road.
  cv::Mat noise(road.size(), CV_16SC1), sum;
  rng.fill(noise, cv::RNG::NORMAL, 0, 6.0);
  road.convertTo(sum, CV_16SC1);
  sum += noise;
  sum.convertTo(frame, CV_8UC1);
  detector.detect(frame);
  CHECK(detector.last_view() == ViewKind::Road);
  // Paint everywhere, over the cap.
  bool cluttered = false;
  for (int k = 0; k < 20 && !cluttered; ++k) {
    detector.detect(clutter_frame(camera, k));
    cluttered = detector.last_view() == ViewKind::Cluttered;
  }
  CHECK(cluttered);
  // Not even looked at.
  detector.detect(cv::Mat(10, 10, CV_8UC1, cv::Scalar(0)));
  CHECK(detector.last_view() == ViewKind::Unusable);
  const DetectorCounters& counters = detector.counters();
  CHECK(counters.flat_frames == 6);
  CHECK(counters.noisy_frames == 3);
  CHECK(counters.bad_frames == 1);
}

TEST_CASE("detector: frames of paint everywhere or noise do not move the horizon") {
  const CameraModel camera = default_camera_model();
  DetectorConfig config;
  config.horizon_from_lanes = true;
  MarkingDetector detector(camera, config);
  for (int k = 0; k < 20; ++k) detector.detect(clutter_frame(camera, k));
  for (int k = 0; k < 20; ++k) detector.detect(garbage_frame(camera, k));
  const DetectorCounters& counters = detector.counters();
  CHECK(counters.frames == 40);
  CHECK(counters.candidates_dropped > 0);
  CHECK(counters.horizon_measured == 0);
  CHECK(counters.horizon_unmeasured == 40);
  CHECK(counters.horizon_moves == 0);
  CHECK(detector.horizon_shift() == 0);
}

TEST_CASE("horizon: lane lines meeting at a point give its row; strays and parallels do not") {
  // Four lines from the bottom of an 800x600 image to a point at (420, 250),
  // each seen over part of its length.
  const float vx = 420.0f, vy = 250.0f;
  std::vector<ImageSegment> lines;
  for (const float foot : {0.0f, 250.0f, 600.0f, 800.0f}) {
    const auto at = [&](float t) {
      return std::array<float, 2>{foot + t * (vx - foot), 600.0f + t * (vy - 600.0f)};
    };
    const auto a = at(0.2f), b = at(0.6f);
    lines.push_back({a[0], a[1], b[0], b[1]});
  }
  const VanishingSearch search{200.0f, 300.0f, -400.0f, 1200.0f};
  const std::optional<float> row = vanishing_row(lines, search);
  REQUIRE(row.has_value());
  CHECK(*row == Catch::Approx(vy).margin(0.01));
  // A kerb bent by a parked car and a shadow across: outvoted.
  lines.push_back({100.0f, 500.0f, 300.0f, 380.0f});
  lines.push_back({500.0f, 420.0f, 700.0f, 300.0f});
  const std::optional<float> with_strays = vanishing_row(lines, search);
  REQUIRE(with_strays.has_value());
  CHECK(*with_strays == Catch::Approx(vy).margin(0.01));
  // Parallel lines meet nowhere; lines meeting outside the rows searched
  // are not the horizon.
  const std::vector<ImageSegment> parallel = {{100, 500, 200, 400}, {300, 500, 400, 400}};
  CHECK_FALSE(vanishing_row(parallel, search).has_value());
  const VanishingSearch elsewhere{300.0f, 400.0f, -400.0f, 1200.0f};
  CHECK_FALSE(vanishing_row(std::span(lines).first(4), elsewhere).has_value());
}

TEST_CASE("detector: the horizon from the lane lines undoes a camera pitched other than calibrated") {
  const CameraModel calibrated = default_camera_model();
  CameraMounting mounting = calibrated.mounting();
  mounting.pitch_rad += 1.0 * std::numbers::pi / 180.0;  // looks 1 degree further down than calibrated
  const CameraModel actual =
      CameraModel::pinhole(calibrated.width(), calibrated.height(), calibrated.intrinsics(), mounting);
  // Four lane lines, dashes between, and a legend-sized block at 10 m.
  std::vector<GroundRect> paint = {{3.0, 40.0, 1.7, 1.85},
                                   {3.0, 40.0, -1.85, -1.7},
                                   {3.0, 40.0, 5.3, 5.45},
                                   {3.0, 40.0, -5.45, -5.3},
                                   {8.8, 11.2, 0.6, 1.2}};
  for (double x = 4.0; x < 40.0; x += 9.0) paint.push_back({x, x + 3.0, -0.08, 0.08});
  const cv::Mat frame = render_road(actual, paint);
  // Pitched down, the camera sees the horizon higher (about 16 rows): the
  // view must be read that much higher.
  Eigen::Vector2d horizon_calibrated, horizon_actual;
  REQUIRE(calibrated.ground_to_image({1.0e5, 0.0}, horizon_calibrated));
  REQUIRE(actual.ground_to_image({1.0e5, 0.0}, horizon_actual));
  const double expected_shift = horizon_actual.y() - horizon_calibrated.y();
  CHECK(expected_shift < -10.0);
  Detection where{};

  DetectorConfig fixed;
  MarkingDetector uncorrected(calibrated, fixed);
  uncorrected.detect_still(frame);
  CHECK(uncorrected.horizon_shift() == 0);
  REQUIRE(nearest(uncorrected, 10.0, 0.9, where) != nullptr);
  CHECK(where.ground_x > 10.8);  // placed too far without the correction

  DetectorConfig config;
  config.horizon_from_lanes = true;
  MarkingDetector still(calibrated, config);
  still.detect_still(frame);
  CHECK(still.horizon_shift() == Catch::Approx(expected_shift).margin(2.0));
  CHECK(still.counters().horizon_measured == 1);
  CHECK(still.counters().frames == 1);
  REQUIRE(nearest(still, 10.0, 0.9, where) != nullptr);
  CHECK(where.ground_x == Catch::Approx(10.0).margin(0.2));
  CHECK(where.ground_y == Catch::Approx(0.9).margin(0.08));
  // The quad is where the block is in the image the camera took.
  Eigen::Vector2d near_left;
  REQUIRE(actual.ground_to_image({8.8, 1.2}, near_left));
  CHECK(where.quad[0][1] == Catch::Approx(near_left.y()).margin(4.0));

  // On a stream, each frame moves the estimate part of the way.
  MarkingDetector stream(calibrated, config);
  stream.detect(frame);
  const int after_one = stream.horizon_shift();
  CHECK(std::abs(after_one) < std::abs(still.horizon_shift()));
  for (int k = 0; k < 120; ++k) stream.detect(frame);
  CHECK(std::abs(stream.horizon_shift() - still.horizon_shift()) <= 1);
  CHECK(stream.counters().horizon_measured == 121);

  // An empty road has no lines: nothing moves.
  MarkingDetector empty(calibrated, config);
  empty.detect_still(render_road(calibrated, {}));
  CHECK(empty.horizon_shift() == 0);
  CHECK(empty.counters().horizon_unmeasured == 1);
}

TEST_CASE("classifier: the compiled-in model fits the features and gives probabilities") {
  const MlpModel& model = builtin_marking_model();
  REQUIRE(model_is_usable(model));
  Features f{};
  std::array<float, kClassifierOutputs> p{};
  const int c = classify(model, f, p);
  CHECK(c >= 0);
  CHECK(c < kClassifierOutputs);
  float total = 0;
  for (float v : p) {
    CHECK(v >= 0.0f);
    total += v;
  }
  CHECK(total == Catch::Approx(1.0f).margin(1e-4));
  MlpModel broken = model;
  broken.nets[broken.members - 1].inputs = kFeatureCount + 1;
  CHECK_FALSE(model_is_usable(broken));
  MlpModel none = model;
  none.members = 0;
  CHECK_FALSE(model_is_usable(none));
}

TEST_CASE("classifier: the probabilities are the mean of the members'") {
  const MlpModel& model = builtin_marking_model();
  REQUIRE(model_is_usable(model));
  REQUIRE(model.members >= 2);  // one member would make the check below trivial
  Features f{};
  for (int i = 0; i < kFeatureCount; ++i) f[i] = 0.01f * static_cast<float>(i % 17);
  std::array<float, kClassifierOutputs> all{}, mean{};
  classify(model, f, all);
  for (int m = 0; m < model.members; ++m) {
    MlpModel one;
    one.members = 1;
    one.nets[0] = model.nets[m];
    std::array<float, kClassifierOutputs> p{};
    classify(one, f, p);
    for (int k = 0; k < kClassifierOutputs; ++k) mean[k] += p[k] / static_cast<float>(model.members);
  }
  for (int k = 0; k < kClassifierOutputs; ++k) CHECK(all[k] == Catch::Approx(mean[k]).margin(1e-6));
}

TEST_CASE("Honda calibration: ground scale and detector region from honda.yaml") {
  const auto camera = load_camera_model(kCameras + "honda.yaml");
  REQUIRE(camera);
  CHECK(camera->width() == 800);
  CHECK(camera->height() == 600);
  // The vanishing point of the published homography (column 400.7, row
  // 261.3) is the horizon: rows just below it are far away, straight ahead.
  Eigen::Vector2d g;
  REQUIRE(camera->image_to_ground({400.7, 300.0}, g));
  CHECK(g.x() == Catch::Approx(13.9).margin(0.2));
  CHECK(g.y() == Catch::Approx(0.0).margin(0.05));
  REQUIRE(camera->image_to_ground({400.7, 350.0}, g));
  CHECK(g.x() == Catch::Approx(6.1).margin(0.1));
  CHECK_FALSE(camera->image_to_ground({400.0, 250.0}, g));  // sky

  const auto loaded = load_detector_config(kCameras + "honda.yaml");
  REQUIRE(loaded);
  const DetectorConfig& config = *loaded;
  CHECK(config.region.x_far_m == Catch::Approx(16.0));
  // The bonnet's outline: highest in the middle of the image.
  REQUIRE(config.hidden_below.count == 10);
  CHECK(config.hidden_below.row_at(375.0f) == Catch::Approx(401.0));
  CHECK(config.hidden_below.row_at(0.0f) == Catch::Approx(438.0));
  CHECK(config.hidden_below.row_at(50.0f) == Catch::Approx(433.0));
  CHECK(config.hidden_below.row_at(900.0f) == Catch::Approx(478.0));
  // Two mountings among the clips: the horizon is measured, the bonnet follows.
  CHECK(config.horizon_from_lanes);
  CHECK(config.hidden_below_follows_horizon);
  // The sim camera's file has no detector keys: defaults stay (it is
  // calibrated exactly: no horizon measured).
  const auto sim = load_detector_config(kCameras + "sim.yaml");
  REQUIRE(sim);
  const DetectorConfig& defaults = *sim;
  CHECK(defaults.region.x_far_m == Catch::Approx(DetectorConfig{}.region.x_far_m));
  CHECK_FALSE(defaults.horizon_from_lanes);
}

TEST_CASE("detector config: bad values are reported with the file") {
  const std::string path = "/tmp/markloop-detector-config-test.yaml";
  DetectorConfig config;
  std::string error;
  // Writes the keys and values given, in turn, and reads the file back.
  const auto load = [&](const auto&... keys_and_values) {
    {
      cv::FileStorage fs(path, cv::FileStorage::WRITE);
      ((fs << keys_and_values), ...);
    }
    markloop::Result<DetectorConfig> loaded = load_detector_config(path, config);
    error = loaded ? std::string() : loaded.message();
    if (loaded) config = *loaded;
    return loaded.ok();
  };
  CHECK_FALSE(load("detector_x_near_m", 10.0, "detector_x_far_m", 5.0));
  CHECK(error.find(path) == 0);
  CHECK(error.find("empty") != std::string::npos);
  CHECK_FALSE(load("detector_min_score", 3.0));
  CHECK(error.find("detector_min_score") != std::string::npos);
  CHECK_FALSE(load("detector_hidden_below", std::vector<int>{0, 400, 300}));
  CHECK(error.find("detector_hidden_below must be a list") != std::string::npos);
  CHECK_FALSE(load("detector_hidden_below", std::vector<int>{0, 400, 300, 420, 200, 430}));
  CHECK(error.find("point 3: columns must increase") != std::string::npos);
  CHECK_FALSE(load("detector_horizon_from_lanes", 2));
  CHECK(error == path + ": detector_horizon_from_lanes must be 0 or 1");
  CHECK_FALSE(load("detector_horizon_max_shift_px", -3));
  CHECK(error.find("detector_horizon_max_shift_px must be a whole number 0..200") != std::string::npos);
  CHECK_FALSE(load("detector_horizon_gain", 0.0));
  CHECK(error.find("detector_horizon_gain") != std::string::npos);
  REQUIRE(load("detector_horizon_from_lanes", 1, "detector_hidden_below_follows_horizon", 1,
               "detector_horizon_max_shift_px", 25, "detector_horizon_gain", 0.1));
  CHECK(config.horizon_from_lanes);
  CHECK(config.hidden_below_follows_horizon);
  CHECK(config.horizon_max_shift_px == 25);
  CHECK(config.horizon_gain == Catch::Approx(0.1));
  CHECK_FALSE(load("detector_guard_m", -0.1));
  CHECK(error.find("detector_guard_m") != std::string::npos);
  REQUIRE(load("detector_guard_m", 0.5));
  CHECK(config.guard_m == Catch::Approx(0.5));
  CHECK_FALSE(load("detector_cnn_share", 1.5));
  CHECK(error.find("detector_cnn_share") != std::string::npos);
  CHECK_FALSE(load("detector_skip_networks_at", "high"));
  CHECK(error == path + ": detector_skip_networks_at must be a number");
  REQUIRE(load("detector_cnn_share", 0.7, "detector_skip_networks_at", 2.0));
  CHECK(config.cnn_share == Catch::Approx(0.7));
  CHECK(config.skip_networks_at == Catch::Approx(2.0));
  const auto missing = load_detector_config("/nonexistent/camera.yaml", config);
  REQUIRE_FALSE(missing);
  CHECK(missing.message().find("/nonexistent/camera.yaml") == 0);
}
