// The revisit events' section of the tools' tables and JSON, the same in
// markloop-eval, markloop-replay and markloop-eval --summary.
#pragma once

#include <cstddef>
#include <cstdio>
#include <span>
#include <string>

#include "app/tools/replay/revisit_events.hpp"

namespace markloop::replay {

// "12.5 %" or "-" when there is nothing to divide by.
std::string percent_of(std::size_t part, std::size_t whole);

// The heading and the tally: closed / total by kind and length, and the
// closure distances.
void print_revisit_tally(std::FILE* out, const RevisitTally& tally);

// One line per event in drive order (first frame, length, kind, closed at
// or never), at most `limit`, then how many more there are.
void print_revisit_events(std::FILE* out, std::span<const RevisitEvent> events, std::size_t limit);

// "\"revisits\":{...}": the definition's constants, every event and the tally.
void json_revisits(std::FILE* out, std::span<const RevisitEvent> events, const RevisitTally& tally);
// The tally alone as a JSON object.
void json_revisit_tally(std::FILE* out, const RevisitTally& tally);

}  // namespace markloop::replay
