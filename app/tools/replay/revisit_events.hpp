// Revisit events of a drive, found in the truth, and how far into each one
// the first correct loop detection reached the bus (issue 64's measure).
// Shared by markloop-eval (detections read back from CAN) and
// markloop-replay (detections from the engine).
//
// A revisit frame is a frame within kRevisitRadius_m of the true position of
// a frame at least kRevisitMinAge_s older. An event is a run of revisit
// frames in which each follows the one before by less than
// kRevisitMaxGap_s; it spans from its first revisit frame to its last (the
// few frames of a gap inside it included). Its length is the distance driven
// from its first frame to its last.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "app/engine/types.hpp"

namespace markloop::replay {

inline constexpr double kRevisitRadius_m = 6.0;
inline constexpr double kRevisitMinAge_s = 30.0;
inline constexpr double kRevisitMaxGap_s = 3.0;
// Headings within this of the old frame's (or of its reverse) are driving
// along the old road the same (or the opposite) way.
inline constexpr double kAlongRoadTolerance_deg = 45.0;
// The events the targets are read on: at least this long.
inline constexpr double kLongRevisit_m = 50.0;
// Markings passed this far before an event's first frame count as the
// event's: the car sees an intersection before it enters the old road.
inline constexpr double kSharedLead_m = 60.0;
// A marking in view is seen when its centre lies in the ground area the
// ECU observes by default: this far ahead of the car (nearer ones are cut
// by the view's edge, farther ones placed too poorly to use), and at most
// this far to either side (the detector's bird's-eye view).
inline constexpr double kSeenNearest_m = 5.5;
inline constexpr double kSeenFarthest_m = 16.0;
inline constexpr double kSeenSide_m = 6.0;

// What a revisit frame does on the old road. Per frame: SameDirection when
// one of the older frames it is near has a heading within
// kAlongRoadTolerance_deg of its own, else OppositeDirection when one lies
// within that of its reverse, else Crossing (the car crosses the old road or
// turns onto or off it). Per event: SameDirection or OppositeDirection when
// frames of that kind cover more than half of the distance driven from its
// revisit frames (each the step to the next frame), else Crossing. A turn at
// a junction followed by 70 m along the old road is SameDirection; a short
// perpendicular pass, or a turn-in that leaves again, is Crossing.
enum class RevisitKind { SameDirection, OppositeDirection, Crossing };
inline constexpr std::size_t kRevisitKindCount = 3;

// "same", "opposite", "crossing" (the JSON's names).
std::string_view revisit_kind_name(RevisitKind kind);
std::optional<RevisitKind> revisit_kind_from_name(std::string_view name);

// Markings an event shares with the older visit: how many the car passes in
// the event (or kSharedLead_m before it), and the distance driven into the
// event when it had passed the second and the third of them (0 when before
// the event). No place of two or three markings can close the event earlier.
struct SharedMarkings {
  std::size_t count = 0;
  std::optional<double> second_m;
  std::optional<double> third_m;
};

struct RevisitEvent {
  std::size_t first_frame = 0;
  std::size_t last_frame = 0;
  double start_m = 0.0;   // distance driven from the drive's first frame to first_frame
  double length_m = 0.0;  // distance driven from first_frame to last_frame
  RevisitKind kind = RevisitKind::Crossing;
  // Set by close_revisit_events: the distance driven from first_frame to the
  // frame at which the first correct detection that closes it reached the
  // bus, and that detection's query frame.
  std::optional<double> closed_at_m;
  std::optional<std::size_t> closing_query_frame;
  // Set by mark_shared_markings: markings in view at least
  // kRevisitMinAge_s before the event, what the world allows.
  std::optional<SharedMarkings> seen;
  // Set by mark_landmarked_markings: markings of which the ECU made a
  // landmark with one label on both visits, what perception allows: places
  // pair only these.
  std::optional<SharedMarkings> landmarked;
};

// `times` in seconds, one per pose, increasing. Events in drive order.
std::vector<RevisitEvent> find_revisit_events(std::span<const Pose2> poses, std::span<const double> times);

// A loop detection as far as closing events goes: its query frame, the
// frame at which it reached the bus (markloop-eval: the latest frame at or
// before its CAN stamp; markloop-replay: the frame the engine was
// processing when it emitted it) and TruthJudge's verdict.
struct ClosingDetection {
  std::size_t query_frame = 0;
  std::size_t bus_frame = 0;
  bool correct = false;
};

// A correct detection closes the event whose frames hold its query frame.
// Each event gets the detection that reached the bus first (the smallest
// distance; never less than 0 m). `poses` are the truth the events were
// found in.
void close_revisit_events(std::vector<RevisitEvent>& events, std::span<const Pose2> poses,
                          std::span<const ClosingDetection> detections);

// A marking in view in a frame (markloop-eval: the simulator's visible.csv)
// and where its centre lies from the car.
struct MarkingView {
  std::size_t frame = 0;
  std::uint32_t marking = 0;
  double ahead_m = 0.0;
  double left_m = 0.0;
};

// Sets every event's shared markings from the markings in view (seen: in
// the area kSeen* describe). A marking is passed at the last frame of its
// first run of sightings in the event or its lead. `poses` and `times` are
// the truth the events were found in; views beyond them are ignored.
void mark_shared_markings(std::vector<RevisitEvent>& events, std::span<const Pose2> poses,
                          std::span<const double> times, std::span<const MarkingView> views);

// A pass of the car by a marking of which the ECU made a landmark
// (markloop-eval: a pass judged with a landmark): the last frame showing it
// and the landmark's label.
struct LandmarkedPass {
  std::size_t last_frame = 0;
  std::uint32_t marking = 0;
  Label label = 0;
};

// Sets every event's landmarked markings: those with a pass ending in the
// event or its lead whose label a pass ending kRevisitMinAge_s before the
// event gave too; each at the first such pass. Frames beyond `poses` and
// `times` are ignored.
void mark_landmarked_markings(std::vector<RevisitEvent>& events, std::span<const Pose2> poses,
                              std::span<const double> times, std::span<const LandmarkedPass> passes);

// Closed over total events of one kind and length bucket.
struct RevisitCount {
  std::size_t closed = 0;
  std::size_t total = 0;
};

// Median and p90 (nearest rank) of the closure distances of the closed
// events; zero when none is closed.
struct ClosureDistances {
  std::size_t count = 0;
  double median_m = 0.0;
  double p90_m = 0.0;
};

struct SharedTally {
  std::size_t known = 0;
  ClosureDistances second;
  ClosureDistances third;
};

// Events summed by kind and by length: [kind][0] shorter than
// kLongRevisit_m, [kind][1] at least that long.
struct RevisitTally {
  std::array<std::array<RevisitCount, 2>, kRevisitKindCount> by_kind{};
  RevisitCount shorter, longer, all;  // over every kind
  ClosureDistances closure_long;      // events of at least kLongRevisit_m
  ClosureDistances closure_all;
  // Events of at least kLongRevisit_m whose shared markings are known, and
  // where their second and third were passed (over those that have one).
  SharedTally seen_long;
  SharedTally landmarked_long;
  // Closed events of at least kLongRevisit_m with a third landmarked
  // marking: how far past it they closed (the engine's own wait; negative
  // when a place or sequence closed it sooner).
  ClosureDistances beyond_third_landmarked_long;
};

RevisitTally tally_revisit_events(std::span<const RevisitEvent> events);

}  // namespace markloop::replay
