// The ECU's saved map (markloop --map): any bytes load, are set aside with a
// reason, or are refused and left alone; never a crash, never half a map.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>

#include "app/ecu/map_store.hpp"
#include "app/engine/sequence_database.hpp"
#include "tests/fuzz/fuzz_input.hpp"

using namespace markloop;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const fuzz::InputFile file(data, size, ".map");
  DatabaseConfig capacity;  // small, so that a file larger than the ring is tried too
  capacity.landmark_capacity = 64;
  capacity.sequence_capacity = 64;
  const MatchConfig match;
  SequenceDatabase database(capacity, match, 4);
  ecu::MapStore store(file.path());
  const ecu::MapLoadResult result = store.load(database, match);
  if (result.outcome == ecu::MapLoadOutcome::kRejected || result.outcome == ecu::MapLoadOutcome::kUnusable) {
    if (result.message.empty() || database.stats().landmarks != 0 || database.stats().sequences != 0)
      std::abort();  // refused with a reason, and nothing of it kept
    if (!result.set_aside_path.empty()) std::remove(result.set_aside_path.c_str());
  } else if (result.outcome == ecu::MapLoadOutcome::kLoaded) {
    // A map larger than the database is refused, so every sequence loads.
    if (database.stats().sequences != result.sequences) std::abort();
  }
  return 0;
}
