// The road-marking classes markloop recognises. The index of a name is its
// Label on the wire and in the database, so the order is part of the map
// file and CAN interface: append new classes, never reorder.
//
// Names follow the real-image dataset's labels (roadmarks-honda) where it
// has the class; the simulator draws exactly these classes.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string_view>

#include "app/engine/types.hpp"

namespace markloop::perception {

inline constexpr std::array<std::string_view, 16> kMarkingClassNames = {
    "forward",       // straight-ahead arrow
    "leftturn",      // left-turn arrow
    "rightturn",     // right-turn arrow
    "forward&left",  // combined arrows
    "forward&right",
    "stop",  // the painted word STOP
    "ped",   // PED
    "xing",  // XING
    "bike",  // bicycle symbol
    "rail",  // railroad crossing "RXR"
    "25",    // speed numbers
    "35",
    "40",
    "diamond",    // HOV / reserved-lane diamond
    "stopline",   // solid line across the lane
    "crosswalk",  // zebra stripes across the road
};

inline constexpr std::size_t kMarkingClassCount = kMarkingClassNames.size();

constexpr std::string_view marking_class_name(Label label) {
  return label < kMarkingClassCount ? kMarkingClassNames[label] : std::string_view("unknown");
}

// True for the classes whose marking turned half way round is the same
// marking: read from behind they look as they do from ahead.
constexpr bool same_when_turned(Label label) {
  const std::string_view name = marking_class_name(label);
  return name == "diamond" || name == "stopline" || name == "crosswalk";
}

// Which way a marking faces the car that read it: read `turned` half way
// round, it is painted for the opposite direction.
constexpr Facing facing_of(Label label, bool turned) {
  if (same_when_turned(label)) return Facing::kAny;
  return turned ? Facing::kAgainst : Facing::kAlong;
}

constexpr std::optional<Label> marking_class_from_name(std::string_view name) {
  for (std::size_t i = 0; i < kMarkingClassCount; ++i)
    if (kMarkingClassNames[i] == name) return static_cast<Label>(i);
  return std::nullopt;
}

}  // namespace markloop::perception
