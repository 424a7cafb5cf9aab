// Road-marking detector: from a grey camera frame to labelled markings on
// the ground.
//
//   grey frame --(lookup-table warp)--> bird's-eye view of the road region
//     --> bright paint: pixel above the local road brightness (integral image)
//     --> connected regions (run-length union-find), lane lines set apart
//         (optionally, where they meet places the horizon: horizon.hpp)
//     --> groups: parts close along and across the road (letters of a word,
//         digits of a number), and a crosswalk's stripes side by side,
//         become one candidate
//     --> features (HOG of the normalised patch, occupancy, size)
//     --> three small MLPs, probabilities averaged, with an explicit reject class
//     --> Detection: label, score, quad in the image, centre on the ground.
//
// Everything is sized in the constructor; detect() does not touch the heap.
// Not thread-safe: one detector per camera thread.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "app/engine/types.hpp"
#include "app/perception/birdseye.hpp"
#include "app/perception/camera_model.hpp"
#include "app/perception/horizon.hpp"
#include "app/perception/marking_classifier.hpp"
#include "app/perception/marking_features.hpp"

namespace markloop::perception {

struct Detection {
  Label label;                               // index into kMarkingClassNames
  float score;                               // classifier confidence 0..1
  std::array<std::array<float, 2>, 4> quad;  // corners in the original image, pixels
  float ground_x, ground_y;                  // centre on the road, vehicle frame, metres
  // detect_still() only: cut by the view's near edge; quad and centre are the
  // visible part's.
  bool partial;
};
inline constexpr std::size_t kMaxDetections = 32;

struct DetectorConfig {
  BirdsEyeRegion region;  // road area searched and its resolution
  // The view reads this much further than `region` beyond its far end and
  // its sides (rounded up to whole pixels): paint smeared by blur reaches a
  // pixel or two past a marking's outline, so one that ends just inside the
  // region would otherwise touch the view's edge and be taken for cut.
  // Candidates centred in this band are classified but not reported
  // (counted in beyond_region).
  float guard_m = 0.3f;
  // Image pixels at or below this outline are the car's bonnet, not road.
  ImageOutline hidden_below;
  // Bright paint: brighter than the mean of a window this size around it by
  // min_contrast grey levels or min_contrast_ratio of the mean, whichever is larger.
  float local_window_m = 1.6f;
  int min_contrast = 14;
  float min_contrast_ratio = 0.12f;
  // ...and brighter than the road of each quarter of that window (the four
  // quadrants meeting at it; a quadrant's road is its pixels less the paint
  // the window's test found) by quadrant_min_contrast grey levels or
  // quadrant_min_contrast_ratio of that road's mean. Any edge through a pixel
  // leaves a whole quadrant on one side of it: sunlit road beside a shadow,
  // which the window's mean (half shadow) lets through, is as bright as its
  // sunlit quadrant and is not paint (0: no such test).
  int quadrant_min_contrast = 7;
  float quadrant_min_contrast_ratio = 0.06f;
  float min_part_area_m2 = 0.02f;  // smaller specks are noise
  // Thin long parts are lane lines or kerbs: never grouped, never classified.
  // Thin and long in their box or along their own axis (second moments), so
  // that a line at an angle to the road counts too.
  float line_max_width_m = 0.30f;
  float line_min_length_m = 2.0f;
  // Large sparse parts (a stop line joined to a lane line, kerbs) are set
  // apart likewise: both sides over sparse_min_size_m, paint under sparse_max_fill,
  // and no road enclosed (a diamond's outline is sparse too).
  float sparse_min_size_m = 2.0f;
  float sparse_max_fill = 0.15f;
  // Where a line along the road (paint run >= junction_along_m) crosses
  // paint across the road (run >= junction_across_m), e.g. a stop line
  // meeting a lane line, the crossing is cut so the two come apart.
  float junction_along_m = 1.0f;
  float junction_across_m = 1.5f;
  // Where the paint across is a bar at least junction_long_bar_m long (a
  // stop line, not an arrow's head), the cut reaches junction_cut_margin_m
  // further along the line: a slanted, blurred or worn edge of the bar,
  // whose rows are too broken to be cut themselves, would otherwise join
  // the two again (a 0.45 m stop line spans about 0.65 m of the view).
  float junction_long_bar_m = 2.5f;
  float junction_cut_margin_m = 0.3f;
  // A worn bar's rows are broken, so none runs unbroken for
  // junction_across_m: a row of a line at least junction_worn_along_m long
  // also counts as crossed where the junction_across_m beside it is at
  // least junction_min_fill paint starting within junction_bridge_m of it
  // (0: unbroken runs only). Longer than a letter: the tops of a word's
  // letters side by side fill a row as densely.
  float junction_min_fill = 0.6f;
  float junction_bridge_m = 0.1f;
  float junction_worn_along_m = 3.0f;
  // Parts whose boxes come closer than this (along, across the road) form one
  // marking; only parts up to group_max_part_m either way are grouped
  // (letters, digits, stripes): arrows are whole already, and lines and
  // kerbs must not swallow the markings next to them.
  float group_gap_along_m = 0.6f;
  float group_gap_across_m = 0.35f;
  float group_max_part_m = 3.2f;
  // A letter that is one straight stroke (the I of XING and BIKE; an N's
  // upright when a shadow breaks its diagonal) is set apart as a line, and
  // the word falls in two candidates, each classified as the word (so the
  // model was trained), which would be two landmarks a metre or two apart.
  // A part set apart as a line but no longer than group_max_part_m, with a
  // candidate within group_gap_across_m on either side, each beside at
  // least stroke_min_shared of its length (a letter of their height, not a
  // 3 m lane dash beside 2.4 m letters) and at most twice as long, links
  // the two; linked candidates of the same class are reported as one
  // (join_across_strokes()).
  float stroke_min_shared = 0.85f;
  // A word's letters a little further apart than the grouping gap (on a
  // bend, XIN and G) fall in two candidates, each classified as the word:
  // candidates of the same word class side by side (sharing
  // stroke_min_shared of the shorter one's rows, at most half as long
  // again), up to word_join_gap_m apart and together at most
  // word_max_width_m across (not the same word in the next lane), are
  // reported as one (join_split_words()).
  float word_join_gap_m = 0.6f;
  float word_max_width_m = 3.2f;
  // A crosswalk's stripes lie further apart across the road than letters
  // (0.5 m and more): stripes (at least stripe_min_length_m along, wider
  // than a line and at most stripe_max_width_m across, paint filling at
  // least stripe_min_fill of their box, which a letter's strokes do not)
  // side by side, sharing stripe_min_shared of the shorter one's rows,
  // group up to stripe_gap_across_m apart. Alone, each stripe would be a
  // crosswalk of its own, a metre from the next.
  float stripe_min_length_m = 1.5f;
  float stripe_max_width_m = 0.8f;
  float stripe_gap_across_m = 0.8f;
  float stripe_min_shared = 0.8f;
  float stripe_min_fill = 0.65f;
  // Bars across the road (stop lines: wide across, short along) are whole
  // markings: grouped, they would swallow lane-line ends and shadow specks.
  float bar_min_width_m = 2.0f;
  float bar_max_length_m = 1.0f;
  float max_marking_length_m = 9.0f;  // larger groups are not markings (cars, shadows' edges)
  float max_marking_width_m = 9.0f;
  // Below: rejected even if a marking class wins. On the real images'
  // cross-validation 0.6 trades a little recall for much precision over
  // 0.5; it is also the ECU's observation gate.
  float min_score = 0.6f;
  // Markings cut by the edge of the view are classified (for training) but
  // not reported: their class and centre are guesses.
  bool report_clipped = false;
  // ... except, from detect_still(), one cut only by the near edge (the
  // bonnet, the image's bottom, the region's near end), which shows its far
  // end whole: a still image has no earlier frame that saw the rest (a
  // stream did, so detect() leaves it out). Reported with `partial` set.
  bool report_partial_in_stills = true;
  // The horizon from the lane lines (horizon.hpp): a camera pitched other
  // than its calibration says sees the road stretched or squashed along the
  // bird's-eye view. When on, each frame's lane lines measure where the
  // horizon is, and the view is read that many image rows lower or higher
  // (at most horizon_max_shift_px) from the next frame on; each frame's
  // measurement moves the estimate by horizon_gain of the difference.
  // detect_still() measures and applies it on the image itself.
  bool horizon_from_lanes = false;
  float horizon_gain = 0.05f;
  int horizon_max_shift_px = 40;
  // The bonnet outline moves with the horizon: on for a camera whose mount
  // is what changes (the real dataset's two recording set-ups), off when
  // the car's own pitch is (the bonnet stays put in the image).
  bool hidden_below_follows_horizon = false;
  // Classifier weights; nullptr: the model compiled in (model/marking_model.cpp).
  const MlpModel* model = nullptr;
  // The convolutional networks blended in (marking_classifier.hpp); nullptr:
  // those compiled in (model/marking_cnn.cpp). cnn_share 0: MLPs alone
  // (detector_cnn_share).
  const CnnModel* cnn = nullptr;
  float cnn_share = 0.5f;
  // The networks are not run where the MLPs call a candidate a reject with
  // at least this probability (marking_classifier.hpp); above 1: always run
  // (detector_skip_networks_at).
  float skip_networks_at = 0.9f;
  // What a view of a road looks like (ViewSpread): its blocks' grey varies
  // by at least min_view_spread (standard deviation, grey levels; less is
  // ViewKind::Flat: a covered lens, darkness, an overexposed or stuck
  // sensor, whatever its noise), and by at least min_view_coherence of its
  // pixels' (less is ViewKind::Noisy: noise averages out in a block, a
  // road's lines, verges and light do not). Other views are not searched
  // for markings. Measured (markloop-detector-bench, markloop-detect): the
  // real images' views 12.7 and more, and 0.69 and more; the simulator's
  // drives in every light 11.0 and more, and 0.63 and more; frames of noise
  // and checkerboards 0.21 at most; the simulator's covered lens 0.15 at
  // most, under 1 with noise of up to 8 grey levels.
  float min_view_spread = 1.0f;
  float min_view_coherence = 0.25f;
};

// Reads the optional detector_* keys of a calibration file (OpenCV YAML), so
// one file describes a camera and the road region it sees; keys absent keep
// `config`'s values. False with `error` = "PATH: what is wrong" on failure.
bool load_detector_config(const std::string& path, DetectorConfig& config, std::string& error);

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
  std::uint64_t joined = 0;               // candidates joined to the one across a letter stroke
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

// One group of bright parts, as classified (exposed for training and tests).
struct Candidate {
  // Box in bird's-eye pixels: columns left to right, rows far to near.
  int col0, row0, col1, row1;  // inclusive
  int parts;
  float length_m, width_m;  // along and across the road
  bool clipped;             // touches the edge of the view: seen only in part
  bool clipped_near_only;   // ... and only its near edge, where the car drives on
  Features features;
  int predicted;  // class index, kRejectClass for "not a marking"
  float score;
  // Index of the candidate across a letter stroke to its right
  // (DetectorConfig::stroke_min_shared), reported with this one when both
  // get the same class; -1 none.
  int across_stroke;
};
inline constexpr std::size_t kMaxCandidates = 64;
inline constexpr std::size_t kMaxParts = 1024;
inline constexpr std::size_t kMaxStrokes = 64;  // line parts short enough to be a letter

// True when at least kPieceMinInside of candidates[index]'s box lies inside
// the box of a larger candidate of the same predicted class, or of one cut by
// the view's edge (whatever it was classified as, seen only in part): a
// piece of that marking (the R either side of a railway crossing's X, which
// may reach a little past the X's box), not one of its own.
inline constexpr float kPieceMinInside = 0.75f;
bool is_piece_of_larger(std::span<const Candidate> candidates, std::size_t index);

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
  std::span<const ImageSegment> lane_segments() const { return {lane_segments_.data(), lane_segment_count_}; }

  const DetectorCounters& counters() const { return counters_; }
  // What the last frame showed, and how much its view's grey varied.
  ViewKind last_view() const { return last_view_; }
  ViewSpread last_view_spread() const { return last_view_spread_; }
  const DetectorConfig& config() const { return config_; }
  const BirdsEyeView& birdseye() const { return birdseye_; }
  // The last frame's bird's-eye image and bright-paint mask (255 = paint).
  const cv::Mat& birdseye_image() const { return bev_; }
  const cv::Mat& paint_mask() const { return mask_; }
  // Every group of the last frame, classified or not.
  std::span<const Candidate> candidates() const { return {candidates_.data(), candidate_count_}; }
  // Per candidate, the one whose detection it is part of (join_across_strokes).
  std::span<const std::int32_t> reported_by() const { return {reported_by_.data(), candidate_count_}; }
  // The quad (image pixels) and ground centre of a candidate's box.
  void locate(const Candidate& candidate, Detection& out) const;
  // True when the candidate's centre lies in the guard band, beyond
  // config().region: it is not reported.
  bool beyond_region(const Candidate& candidate) const;

 private:
  struct Part {
    int col0, row0, col1, row1;
    int area;
    int group;
    bool thin;  // as thin as a line along its own axis (a dash's piece, seen at any angle)
  };
  // Sums over a provisional label's pixels, for its axis.
  struct Moments {
    std::int64_t row, col, row_row, col_col, row_col;
  };
  // A part's principal axis on the ground: the length and width of the bar
  // with the same second moments, its angle from the road's direction.
  struct Axis {
    double mean_row, mean_col;
    double length_m, width_m;
    double angle_rad;
  };
  Axis axis(const Part& box, const Moments& sums) const;
  // True when the paint of `label` (a root label) encloses road of at least
  // kMinEnclosedM2 inside its box: a closed outline (a diamond), no line.
  bool encloses_road(int label, const Part& box);

  void threshold();
  void veto_one_sided_paint();
  void cut_line_junctions();
  std::size_t label_parts();
  void group_parts(std::size_t part_count);
  // Links the candidates either side of each letter-like stroke
  // (Candidate::across_stroke), and marks as cut those across a stroke from
  // letters cut by the view's edge: the word is seen only in part.
  void link_across_strokes(int gap_cols);
  // True when a stroke, or one within gap_cols of it towards `side` (+1 its
  // right, -1 its left) along most of its rows, touches the view's side or
  // far edge.
  bool runs_out_of_view(const Part& stroke, int side, int gap_cols) const;
  void classify(Candidate& candidate);
  // A candidate's box on the ground (vehicle frame, metres).
  struct GroundBox {
    float far, near, left, right;
  };
  GroundBox ground_box(const Candidate& candidate) const;
  // kNearEdge | kOtherEdge bits of the edge pixels the paint in a box (a
  // Candidate's or a Part's) touches.
  template <typename Box>
  std::uint8_t touched_edges(const Box& box) const;
  bool usable(const cv::Mat& grey) const;
  std::span<const Detection> reject_frame();
  // Counts last_view_, as process() judged the frame, and returns it.
  ViewKind count_view();
  // Flat, Noisy or Road, from the spread alone (config_.min_view_*).
  ViewKind kind_of(ViewSpread spread) const;
  ViewSpread view_spread() const;
  std::span<const Detection> detect_frame(const cv::Mat& grey, bool still);
  void process(const cv::Mat& grey, bool still);
  void note_lane_segment(const Axis& axis);
  std::optional<float> measure_horizon_shift() const;
  void set_horizon_shift(int rows);
  void update_view_masks();

  CameraModel camera_;
  DetectorConfig config_;
  BirdsEyeView birdseye_;
  const MlpModel* model_;
  const CnnModel* cnn_;
  int window_cols_ = 1, window_rows_ = 1;
  int word_gap_cols_ = 0, word_max_cols_ = 0;  // word_join_gap_m, word_max_width_m
  int min_part_area_px_ = 1;

  cv::Mat bev_;             // CV_8UC1 bird's-eye image
  cv::Mat mask_;            // CV_8UC1 paint mask
  cv::Mat integral_;        // CV_32SC1 (rows+1) x (cols+1): bird's-eye sums
  cv::Mat valid_integral_;  // CV_32SC1: counts of valid pixels (for the view's row shift)
  // CV_8UC2 {value, 1}: the road's pixels (valid, not painted by the
  // window test), 0 elsewhere; CV_32SC2: their integral, interleaved so that
  // a quadrant's sum and count share cache lines.
  cv::Mat road_pixels_, road_integral_;
  cv::Mat at_edge_;  // CV_8UC1: kNearEdge / kOtherEdge where a pixel borders what is not seen
  // For update_view_masks(): one row's kind of unseen per pixel (kNearEdge:
  // below, kOtherEdge: elsewhere, 0: seen), and per pixel (CV_8UC1) those of
  // it and its left and right neighbours ORed.
  std::vector<std::uint8_t> unseen_kind_row_;
  cv::Mat unseen_kind_across_;
  std::vector<std::int16_t> run_above_;      // paint run length down to each pixel
  std::vector<std::int16_t> run_below_;      // ... and from it downwards
  std::vector<std::int32_t> pixel_labels_;   // provisional label per pixel, -1 none
  std::vector<std::int32_t> parent_;         // union-find over provisional labels
  std::vector<Part> label_box_;              // box and area per provisional label
  std::vector<Moments> label_moments_;       // pixel sums per provisional label
  std::vector<std::uint8_t> fill_reached_;   // encloses_road(): pixels reached from the box's border
  std::vector<std::int32_t> fill_queue_;     // ... and those still to visit
  std::vector<Part> parts_;                  // kMaxParts
  std::array<Part, kMaxStrokes> strokes_{};  // line parts short enough to be a letter
  std::size_t stroke_count_ = 0;
  std::vector<std::int32_t> group_parent_;     // union-find over parts
  std::vector<std::uint8_t> part_groupable_;   // per part: may join a group (bit 1), as a stripe (bit 2)
  std::vector<std::int32_t> group_candidate_;  // group root -> candidate index
  std::array<Candidate, kMaxCandidates> candidates_{};
  std::size_t candidate_count_ = 0;
  std::array<std::int32_t, kMaxCandidates> reported_by_{};  // join_across_strokes()
  std::array<Detection, kMaxDetections> detections_{};
  std::size_t detection_count_ = 0;
  PatchScratch scratch_;
  CnnScratch cnn_scratch_;
  // Lane lines of the last frame, the longest kMaxHorizonSegments.
  std::array<ImageSegment, kMaxHorizonSegments> lane_segments_{};
  std::array<float, kMaxHorizonSegments> lane_lengths_{};
  std::size_t lane_segment_count_ = 0;
  float calibrated_horizon_row_ = 0.0f;  // the image row of the road's horizon, straight ahead
  bool horizon_known_ = false;           // the calibration places the horizon
  float horizon_estimate_ = 0.0f;        // rows below the calibration's, smoothed
  ViewKind last_view_ = ViewKind::Unusable;
  ViewSpread last_view_spread_;
  DetectorCounters counters_;
};

}  // namespace markloop::perception
