// Road-marking detector: from a grey camera frame to labelled markings on
// the ground. MarkingDetector is the pipeline: it owns the stages (each a
// type of its own under detector/, with its part of DetectorConfig and its
// scratch memory) and runs them in order.
//
//   grey frame --(lookup-table warp)--> bird's-eye view of the road region
//     --> PaintMask: bright paint, a pixel above the local road brightness
//         (integral image); lines crossing paint across the road cut apart
//     --> PartLabeller: connected regions (run-length union-find), lane
//         lines set apart (optionally, where they meet places the horizon:
//         LaneHorizon, horizon.hpp)
//     --> PartGrouper: parts close along and across the road (letters of a
//         word, digits of a number), and a crosswalk's stripes side by
//         side, become one candidate
//     --> CandidateClassifier: features (HOG of the normalised patch,
//         occupancy, size) to three small MLPs and the networks blended
//         with them, with an explicit reject class
//     --> WordJoiner: a word's candidates reported as one
//     --> CrosswalkJoiner: a crosswalk seen from the side, its stripes
//         taken for stop lines one behind the other, reported as one
//     --> MarkingLocator: Detection: label, score, quad in the image,
//         centre on the ground.
//
// Everything is sized in the constructor; detect() does not touch the heap.
// Not thread-safe: one detector per camera thread.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>

#include <opencv2/core/mat.hpp>

#include "app/perception/birdseye.hpp"
#include "app/perception/camera_model.hpp"
#include "app/perception/detector/candidate.hpp"
#include "app/perception/detector/candidate_classifier.hpp"
#include "app/perception/detector/crosswalk_joiner.hpp"
#include "app/perception/detector/detector_config.hpp"
#include "app/perception/detector/detector_counters.hpp"
#include "app/perception/detector/lane_horizon.hpp"
#include "app/perception/detector/marking_locator.hpp"
#include "app/perception/detector/paint_mask.hpp"
#include "app/perception/detector/part_grouper.hpp"
#include "app/perception/detector/part_labeller.hpp"
#include "app/perception/detector/view_edges.hpp"
#include "app/perception/detector/word_joiner.hpp"
#include "app/perception/horizon.hpp"

namespace markloop::perception {

// How much the grey of a bird's-eye view varies (standard deviation, grey
// levels) pixel by pixel and between the means of blocks 16 pixels square.
struct ViewSpread {
  float pixels = 0.0f;
  float blocks = 0.0f;
};

// What the last frame's bird's-eye view showed, for the camera's health: a
// camera whose frames show no road for long is blind (the ECU's fault).
enum class ViewKind : std::uint8_t {
  Road,       // what a road can look like (with or without markings)
  Flat,       // hardly any contrast (min_view_spread)
  Noisy,      // contrast pixel to pixel only, none block to block (min_view_coherence)
  Cluttered,  // paint beyond the detector's caps (examined in part): nothing reported
  Unusable,   // the wrong size or type: not looked at
};

// True when at least kPieceMinInside of candidates[index]'s box lies inside
// the box of a larger candidate of the same predicted class, or of one cut by
// the view's edge (whatever it was classified as, seen only in part): a
// piece of that marking (the R either side of a railway crossing's X, which
// may reach a little past the X's box), not one of its own.
inline constexpr float kPieceMinInside = 0.75f;
bool is_piece_of_larger(std::span<const Candidate> candidates, std::size_t index);

class MarkingDetector {
 public:
  explicit MarkingDetector(const CameraModel& camera, const DetectorConfig& config = {});
  MarkingDetector(const MarkingDetector&) = delete;
  MarkingDetector& operator=(const MarkingDetector&) = delete;

  // `grey`: CV_8UC1 of the camera's size (other frames are counted in
  // bad_frames and give no detections). The result stays valid until the
  // next call.
  std::span<const Detection> detect(const cv::Mat& grey);
  // For an image unrelated to the frames before it: with horizon_from_lanes,
  // its own lane lines place the horizon (the view is warped again where
  // they put it, up to three looks in all); otherwise as detect().
  std::span<const Detection> detect_still(const cv::Mat& grey);

  // Image rows the view is read below the calibration's (horizon_from_lanes).
  int horizon_shift() const { return birdseye_.row_shift(); }
  // The last frame's lane lines in the image, as the horizon measurement saw them.
  std::span<const ImageSegment> lane_segments() const { return lanes_.segments(); }

  const DetectorCounters& counters() const { return counters_; }
  // What the last frame showed, and how much its view's grey varied.
  ViewKind last_view() const { return last_view_; }
  ViewSpread last_view_spread() const { return last_view_spread_; }
  const DetectorConfig& config() const { return config_; }
  const BirdsEyeView& birdseye() const { return birdseye_; }
  // The last frame's bird's-eye image and bright-paint mask (255 = paint).
  const cv::Mat& birdseye_image() const { return bev_; }
  const cv::Mat& paint_mask() const { return paint_.mask(); }
  // Every group of the last frame, classified or not.
  std::span<const Candidate> candidates() const { return {candidates_.data(), candidate_count_}; }
  // Per candidate, the one whose detection it is part of (join_across_strokes).
  std::span<const std::int32_t> reported_by() const { return {reported_by_.data(), candidate_count_}; }
  // The quad (image pixels) and ground centre of a candidate's box.
  void locate(const Candidate& candidate, Detection& out) const { locator_.locate(candidate, out); }
  // True when the candidate's centre lies in the guard band, beyond
  // config().region: it is not reported.
  bool beyond_region(const Candidate& candidate) const { return locator_.beyond_region(candidate); }

 private:
  bool usable(const cv::Mat& grey) const;
  std::span<const Detection> reject_frame();
  std::span<const Detection> detect_frame(const cv::Mat& grey, bool still);
  // Moves the view to the lane lines' horizon, smoothed (detect()).
  void follow_horizon();
  // Counts last_view_, as process() judged the frame, and returns it.
  ViewKind count_view();
  // Flat, Noisy or Road, from the spread alone (config_.min_view_*).
  ViewKind kind_of(ViewSpread spread) const;
  ViewSpread view_spread() const;
  // Every stage in order on one frame.
  void process(const cv::Mat& grey, bool still);
  // Paint, parts, groups: candidates_ (not classified yet).
  void find_candidates();
  // Detections from the classified candidates, words joined.
  void report(bool still, bool any_joined);
  // False, counted by why, when the candidate (index `i`) is not reported.
  bool reportable(const Candidate& candidate, std::size_t i, bool partial);
  void set_horizon_shift(int rows);

  CameraModel camera_;
  DetectorConfig config_;
  BirdsEyeView birdseye_;
  cv::Mat bev_;  // CV_8UC1 bird's-eye image
  ViewEdges edges_;
  LaneHorizon lanes_;
  PaintMask paint_;
  PartLabeller labeller_;
  PartGrouper grouper_;
  CandidateClassifier classifier_;
  WordJoiner words_;
  CrosswalkJoiner crosswalks_;
  MarkingLocator locator_;
  std::array<Candidate, kMaxCandidates> candidates_{};
  std::size_t candidate_count_ = 0;
  std::array<std::int32_t, kMaxCandidates> reported_by_{};  // WordJoiner, CrosswalkJoiner
  std::array<Detection, kMaxDetections> detections_{};
  std::size_t detection_count_ = 0;
  float horizon_estimate_ = 0.0f;  // rows below the calibration's, smoothed
  ViewKind last_view_ = ViewKind::Unusable;
  ViewSpread last_view_spread_;
  DetectorCounters counters_;
};

}  // namespace markloop::perception
