// The figures markloop-eval reports: loop detections judged against the
// truth (TruthJudge, shared with markloop-replay), their latency on the bus,
// and marking detection/classification against the visible markings.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "eval/can_log.hpp"
#include "eval/inputs.hpp"
#include "perception/marking_classes.hpp"
#include "replay/truth_judge.hpp"

namespace markloop::eval {

enum class Verdict { Correct, Wrong, Unjudged };

struct LoopOutcome {
  replay::FramePair pair;
  Verdict verdict = Verdict::Unjudged;
  double true_distance_m = 0.0;             // between the two frames' true positions
  std::optional<replay::PoseError> pose_error;  // detections with PoseValid, correct or wrong
  double latency_s = 0.0;                   // CAN stamp - QueryTime
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
  Spread latency_s;     // CAN stamp - QueryTime
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

// One pass of the car by a marking: the frames in which the simulator shows
// it, none more than kPassGap_s after the one before (a revisit comes back
// at least 10 s later; a vehicle in front hides a marking for less).
inline constexpr double kPassGap_s = 5.0;
// visible.csv leaves a marking out while a vehicle hides its centre or the
// image cuts it; detections are sought in those frames of a pass, and up to
// this long before and after it.
inline constexpr double kPassMargin_s = 1.0;

// The ECU's landmark tracker joins a detection to a track within this
// distance on the ground (engine TrackerConfig's default).
inline constexpr double kSameMarking_m = 1.5;

// A pass counts when the marking's centre lay in the detector's default
// region in one of its frames, in the car's frame (frames.csv's pose), and
// the marking was out of view at the drive's first and last frames.
struct PassRegion {
  double ahead_min_m = 3.0;
  double ahead_max_m = 20.0;
  double side_m = 6.0;
};

// What the ECU's landmark vote (LandmarkTracker) would make of the
// detections paired with a marking over one pass: the label with the most
// votes, ties to the one detected first, wins when it holds at least half
// of them; fewer than two make no landmark.
enum class PassOutcome { NamedRight, NamedWrong, NoMajority, DetectedOnce, NotDetected };
inline constexpr std::size_t kPassOutcomeCount = 5;

struct MarkingPass {
  std::uint32_t id = 0;
  Label label = 0;
  FrameIndex first_frame = 0, last_frame = 0;
  std::size_t detections = 0;  // paired with the marking in the pass
  Label named = 0;             // the vote's winner, when there were detections
  PassOutcome outcome = PassOutcome::NotDetected;
};

struct PassScore {
  std::vector<MarkingPass> passes;  // in range, by first frame
  // In range, but in view at the drive's first or last frame: not driven
  // past within the drive, so not judged.
  std::size_t cut_by_drive_ends = 0;
  std::array<std::size_t, kPassOutcomeCount> outcomes{};
  std::array<std::size_t, perception::kMarkingClassCount> passes_of_class{};
  std::array<std::size_t, perception::kMarkingClassCount> named_right_of_class{};
  std::size_t count(PassOutcome o) const { return outcomes[static_cast<std::size_t>(o)]; }
};

// Judges every marking the car drove past by the landmark vote on the
// detections `markings` paired with it, and on the unpaired ones within
// kSameMarking_m of it on the ground in the frames of the pass that
// visible.csv leaves it out of, and up to kPassMargin_s around the pass.
// `route` and `frame_times` are frames.csv's; `truth` and `detections`
// (sorted by frame) what `markings` was scored on. A visible marking missing
// from `world` is not judged; inputs that do not fit one another give an
// empty score.
PassScore score_passes(const std::vector<WorldMarking>& world, const std::vector<Pose2>& route,
                       const std::vector<double>& frame_times, const std::vector<VisibleMarking>& truth,
                       const std::vector<DetectionRecord>& detections, const MarkingScore& markings,
                       const PassRegion& region = {});

double intersection_over_union(const Quad& a, const Quad& b);
bool centre_inside(const Quad& detection, const Quad& truth);

}  // namespace markloop::eval
