// The figures markloop-eval reports: loop detections judged against the
// truth (TruthJudge, shared with markloop-replay), their latency on the bus,
// and marking detection/classification against the visible markings.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "app/engine/config.hpp"
#include "app/perception/marking_classes.hpp"
#include "app/tools/eval/can_log.hpp"
#include "app/tools/eval/inputs.hpp"
#include "app/tools/replay/revisit_events.hpp"
#include "app/tools/replay/truth_judge.hpp"

namespace markloop::eval {

enum class Verdict { Correct, Wrong, Unjudged };

struct LoopOutcome {
  replay::FramePair pair;
  Verdict verdict = Verdict::Unjudged;
  double true_distance_m = 0.0;                 // between the two frames' true positions
  std::optional<replay::PoseError> pose_error;  // detections with PoseValid, correct or wrong
  double latency_s = 0.0;                       // CAN stamp - QueryTime
};

// Order statistics of a sample; all zero when `count` is 0.
struct Spread {
  std::size_t count = 0;
  double median = 0.0;
  double p99 = 0.0;  // nearest rank
  double max = 0.0;
  double min = 0.0;
};
Spread spread_of(std::vector<double> values);

struct LoopScore {
  replay::Evaluation evaluation;
  std::vector<LoopOutcome> outcomes;  // one per detection, in log order
  Spread latency_s;                   // CAN stamp - QueryTime
  // CAN stamp - frames.csv's time of QueryFrame: from the image of the query
  // place to the bus, including the engine's wait for the markings ahead.
  Spread since_query_frame_s;
  // CAN stamp - time of the latest frame at or before it: the ECU's processing
  // time after the frame that released the detection arrived (meaningful
  // while processing stays under one frame period).
  Spread processing_s;
  // QueryTime (the DBC: capture time of the frame that completed the
  // detection) earlier than QueryFrame's time or later than the send, beyond
  // the signal's 1 ms resolution.
  std::size_t query_time_inconsistent = 0;
};

// `frame_times`: frames.csv's t per frame (same length as the judge's truth).
LoopScore score_loops(const replay::TruthJudge& judge, const std::vector<double>& frame_times,
                      const std::vector<LoopReport>& loops);

// Each detection of `score` (scored from `loops`) as it closes revisit
// events: its query frame, the latest frame at or before its CAN stamp (the
// first when it went out before any), and whether it is correct.
std::vector<replay::ClosingDetection> closing_detections(const LoopScore& score,
                                                         const std::vector<LoopReport>& loops,
                                                         const std::vector<double>& frame_times);

inline constexpr double kMinIntersectionOverUnion = 0.3;

struct ClassScore {
  std::size_t truth = 0;               // visible markings of this class
  std::size_t truth_found = 0;         // ... matched by a detection of any label
  std::size_t truth_right_label = 0;   // ... matched by a detection of this label
  std::size_t detections = 0;          // detections labelled with this class
  std::size_t detections_matched = 0;  // ... matching a visible marking of any class
};

struct MarkingScore {
  std::size_t truth = 0;
  std::size_t detections = 0;
  std::size_t matched = 0;      // one-to-one pairs
  std::size_t right_label = 0;  // pairs whose labels agree
  std::array<ClassScore, perception::kMarkingClassCount> per_class{};
  // confusion[truth class][detected label], over matched pairs.
  std::array<std::array<std::size_t, perception::kMarkingClassCount>, perception::kMarkingClassCount>
      confusion{};
  // Per row of the visible markings: the label of the detection paired with it.
  std::vector<std::optional<Label>> paired_label;
  // Per detection: paired with a visible marking.
  std::vector<bool> detection_paired;
};

// A detection and a visible marking of the same frame match when the centre
// of the detection's quad lies inside the marking's quad, or their
// intersection over union is at least kMinIntersectionOverUnion. Pairs are
// made one to one, best overlap first. Both inputs sorted by frame.
MarkingScore score_markings(const std::vector<VisibleMarking>& truth,
                            const std::vector<DetectionRecord>& detections);

// The ECU's landmarks placed in the truth's world: each one's offset from
// the car at its last_frame (both in the ECU's odometry frame, so the drift
// cancels) applied to the car's true pose in that frame. A landmark lies on
// the nearest marking within kLandmarkOnMarking_m of that place: of its
// centre, or for a crosswalk, which spans the road and is detected lane by
// lane, of the line across the road through its centre, up to
// kCrosswalkReach_m either side.
inline constexpr double kLandmarkOnMarking_m = 2.0;
inline constexpr double kCrosswalkReach_m = 8.0;

// A placed landmark not on a marking of its label, with what a reader needs
// to look it up: where it lies in the truth's world, and the nearest marking
// at any distance.
struct MisplacedLandmark {
  std::size_t landmark = 0;  // its row among the landmarks file's, from 0
  double x = 0.0, y = 0.0;
  std::optional<std::size_t> nearest;  // index in `world`; none in an empty world
  double distance_m = 0.0;             // to the nearest, as kLandmarkOnMarking_m is judged
};

struct LandmarkScore {
  std::size_t landmarks = 0;
  std::size_t without_pose = 0;  // no car pose (or a frame beyond the truth): not placed, not judged
  std::size_t right_label = 0;   // on a marking of its label
  std::size_t wrong_label = 0;   // on a marking of another class
  std::size_t on_nothing = 0;    // on no marking
  // Per landmark: the index in `world` of the marking it lies on.
  std::vector<std::optional<std::size_t>> marking_of;
  // Per landmark, when placed: its distance from that place to the marking.
  Spread distance_m;
  // On a marking of another class or on none, in the file's order.
  std::vector<MisplacedLandmark> misplaced;
};

LandmarkScore score_landmarks(const std::vector<WorldMarking>& world, const std::vector<Pose2>& route,
                              const std::vector<LandmarkRecord>& landmarks);

// One pass of the car by a marking: the frames in which the simulator shows
// it, none more than kPassGap_s after the one before (a revisit comes back
// at least 10 s later; a vehicle in front hides a marking for less).
inline constexpr double kPassGap_s = 5.0;
// visible.csv leaves a marking out while a vehicle hides its centre or the
// image cuts it: a pass reaches this long before and after its frames.
inline constexpr double kPassMargin_s = 1.0;
// The ECU's landmark tracker joins a detection to a track within this
// distance on the ground.
inline constexpr double kSameMarking_m = TrackerConfig{}.association_radius_m;

// A pass counts when the marking's centre lay in this region in one of its
// frames, in the car's frame (frames.csv's pose; the car's lane and the next
// ones, kept whatever the detector's region so that figures stay
// comparable), the marking was out of view at the drive's first frame, and
// the drive went on for kSettleDistance_m after the pass: the ECU holds a
// landmark back until the car is past it (engine.release_lag_m at most), and
// a drive's last tracks are never committed.
struct PassRegion {
  double ahead_min_m = 3.0;
  double ahead_max_m = 20.0;
  double side_m = 6.0;
};
inline constexpr double kSettleDistance_m = 40.0;

// What the ECU made of a pass: a landmark on the marking, seen during the
// pass, with the marking's class or another; or none.
enum class PassOutcome { NamedRight, NamedWrong, NoLandmark };
inline constexpr std::size_t kPassOutcomeCount = 3;

struct MarkingPass {
  std::uint32_t id = 0;
  Label label = 0;
  FrameIndex first_frame = 0, last_frame = 0;  // the frames showing it
  // Detections of it: paired with it where shown, within kSameMarking_m of
  // it on the ground in the pass's other frames.
  std::size_t detections = 0;
  Label named = 0;  // the landmark's label, unless NoLandmark
  PassOutcome outcome = PassOutcome::NoLandmark;
};

struct PassScore {
  std::vector<MarkingPass> passes;  // in range, by first frame
  // In range, but in view at the drive's first frame or too near its end:
  // not judged.
  std::size_t cut_by_drive_ends = 0;
  std::array<std::size_t, kPassOutcomeCount> outcomes{};
  std::array<std::size_t, perception::kMarkingClassCount> passes_of_class{};
  std::array<std::size_t, perception::kMarkingClassCount> named_right_of_class{};
  std::size_t count(PassOutcome o) const { return outcomes[static_cast<std::size_t>(o)]; }
};

// Judges every marking the car drove past by the landmark the ECU made of
// it: one that `placed` puts on the marking and whose frames meet the pass's
// (kPassMargin_s around the frames showing it); of several, the one with
// the most observations. `route` and `frame_times` are frames.csv's;
// `truth` and `detections` (sorted by frame) what `markings` was scored on.
// A visible marking missing from `world` is not judged; inputs that do not
// fit one another give an empty score.
PassScore score_passes(const std::vector<WorldMarking>& world, const std::vector<Pose2>& route,
                       const std::vector<double>& frame_times, const std::vector<VisibleMarking>& truth,
                       const std::vector<DetectionRecord>& detections, const MarkingScore& markings,
                       const std::vector<LandmarkRecord>& landmarks, const LandmarkScore& placed,
                       const PassRegion& region = {});

double intersection_over_union(const Quad& a, const Quad& b);
bool centre_inside(const Quad& detection, const Quad& truth);

}  // namespace markloop::eval
