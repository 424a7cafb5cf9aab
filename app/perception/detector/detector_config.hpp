// The road-marking detector's settings, grouped by the stage that reads
// them (marking_detector.hpp runs the stages in this order). DetectorConfig
// is all of them together, so that a setting is still named
// `config.min_score`, while each stage is given its own part only.
#pragma once

#include <string>

#include "app/common/result.hpp"
#include "app/perception/birdseye.hpp"
#include "app/perception/marking_classifier.hpp"

namespace markloop::perception {

// The bird's-eye view of the road and whether it shows a road at all.
struct ViewConfig {
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
  // What a view of a road looks like (ViewSpread): its blocks' grey varies
  // by at least min_view_spread (standard deviation, grey levels; less is
  // ViewKind::Flat: a covered lens, darkness, an overexposed or stuck
  // sensor, whatever its noise), and by at least min_view_coherence of its
  // pixels' (less is ViewKind::Noisy: noise averages out in a block, a
  // road's lines, verges and light do not). Other views are not searched
  // for markings. markloop-detector-bench and markloop-detect print the
  // spreads a set of frames shows.
  float min_view_spread = 1.0f;
  float min_view_coherence = 0.25f;
};

// The horizon from the lane lines (horizon.hpp): a camera pitched other
// than its calibration says sees the road stretched or squashed along the
// bird's-eye view. When on, each frame's lane lines measure where the
// horizon is, and the view is read that many image rows lower or higher
// (at most horizon_max_shift_px) from the next frame on; each frame's
// measurement moves the estimate by horizon_gain of the difference.
// detect_still() measures and applies it on the image itself.
struct HorizonConfig {
  bool horizon_from_lanes = false;
  float horizon_gain = 0.05f;
  int horizon_max_shift_px = 40;
  // The bonnet outline moves with the horizon: on for a camera whose mount
  // is what changes (the real dataset's two recording set-ups), off when
  // the car's own pitch is (the bonnet stays put in the image).
  bool hidden_below_follows_horizon = false;
};

// Paint mask (PaintMask): which pixels of the view are bright paint, and
// where lines crossing each other are cut apart.
struct PaintMaskConfig {
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
};

// Part labelling (PartLabeller): connected regions of paint, with lines and
// kerbs set apart.
struct PartConfig {
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
  // Larger parts (and groups) are not markings (cars, shadows' edges).
  float max_marking_length_m = 9.0f;
  float max_marking_width_m = 9.0f;
};

// Grouping (PartGrouper): parts that make one marking become one candidate.
struct GroupingConfig {
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
};

// Word joining (WordJoiner): a word's candidates reported as one.
struct WordConfig {
  // A word's letters a little further apart than the grouping gap (on a
  // bend, XIN and G) fall in two candidates, each classified as the word:
  // candidates of the same word class side by side (sharing
  // stroke_min_shared of the shorter one's rows, at most half as long
  // again), up to word_join_gap_m apart and together at most
  // word_max_width_m across (not the same word in the next lane), are
  // reported as one (join_split_words()).
  float word_join_gap_m = 0.6f;
  float word_max_width_m = 3.2f;
};

// Side-crosswalk joining (CrosswalkJoiner): a crosswalk seen from the side
// shows its stripes as bars one behind the other, each classified as a
// stop line; at least side_crosswalk_min_bars of them, each sharing
// side_crosswalk_min_shared of the narrower one's columns, at a pitch
// within side_crosswalk_pitch_*_m and evenly spaced, are reported as one
// crosswalk (detector_side_crosswalks, 0 or 1).
struct SideCrosswalkConfig {
  bool side_crosswalks = true;
  int side_crosswalk_min_bars = 3;
  float side_crosswalk_min_shared = 0.7f;
  float side_crosswalk_pitch_min_m = 0.6f;
  float side_crosswalk_pitch_max_m = 1.6f;
  float side_crosswalk_pitch_tolerance = 0.25f;  // of the first pitch
};

// Classification (CandidateClassifier).
struct ClassifierConfig {
  // Classifier weights; nullptr: the model compiled in (model/marking_mlp.bin).
  const MlpModel* model = nullptr;
  // The convolutional networks blended in (marking_classifier.hpp); nullptr:
  // those compiled in (model/marking_cnn.bin). cnn_share 0: MLPs alone
  // (detector_cnn_share).
  const CnnModel* cnn = nullptr;
  float cnn_share = 0.5f;
  // The networks are not run where the MLPs call a candidate a reject with
  // at least this probability (marking_classifier.hpp); above 1: always run
  // (detector_skip_networks_at).
  float skip_networks_at = 0.9f;
  // A candidate not surely a marking as it lies is read again turned half
  // way round, so that a marking seen from behind (the oncoming lane's
  // arrows, words and numbers) is named as it was painted; the turned
  // reading is taken when it names such a marking with at least this
  // probability. Above 1: never read turned (detector_turned_min_score).
  float turned_min_score = 0.9f;
};

// Reporting: which classified candidates become detections.
struct ReportConfig {
  // Below: rejected even if a marking class wins (a trade of recall for
  // precision: docs/results.md). It is also the ECU's observation gate.
  float min_score = 0.6f;
  // Markings cut by the edge of the view are classified (for training) but
  // not reported: their class and centre are guesses.
  bool report_clipped = false;
  // ... except, from detect_still(), one cut only by the near edge (the
  // bonnet, the image's bottom, the region's near end), which shows its far
  // end whole: a still image has no earlier frame that saw the rest (a
  // stream did, so detect() leaves it out). Reported with `partial` set.
  bool report_partial_in_stills = true;
};

struct DetectorConfig : ViewConfig,
                        HorizonConfig,
                        PaintMaskConfig,
                        PartConfig,
                        GroupingConfig,
                        WordConfig,
                        SideCrosswalkConfig,
                        ClassifierConfig,
                        ReportConfig {};

// Reads the optional detector_* keys of a calibration file (OpenCV YAML), so
// one file describes a camera and the road region it sees; keys absent keep
// `defaults`' values. An error says "PATH: what is wrong".
Result<DetectorConfig> load_detector_config(const std::string& path, const DetectorConfig& defaults = {});

}  // namespace markloop::perception
