// The database's size checked before it is allocated: a capacity inside the
// documented range that this machine cannot hold is an error naming the
// setting, never std::bad_alloc or the OOM killer.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <string>

#include "app/engine/config.hpp"
#include "app/engine/sequence_database.hpp"
#include "platform/files.hpp"

namespace markloop::cli {

// Empty when the database for `config` and `k` fits in the memory available
// now; else what is wrong, naming the two settings as the program calls them.
inline std::string database_memory_error(const DatabaseConfig& config, unsigned k,
                                         const char* landmark_setting, const char* sequence_setting) {
  const std::uint64_t needed = SequenceDatabase::bytes_needed(config, k);
  // A 32-bit target cannot address more than half its pointer range in one go.
  const std::uint64_t addressable = std::numeric_limits<std::size_t>::max() / 2;
  const std::uint64_t memory = platform::available_memory_bytes();
  const std::uint64_t available = memory == 0 ? addressable : std::min(memory, addressable);
  if (needed <= available) return {};
  char text[512];
  std::snprintf(text, sizeof text,
                "%s = %zu and %s = %zu (k = %u) need %.1f MiB for the database, more than the %.1f MiB "
                "of memory available: lower them",
                landmark_setting, config.landmark_capacity, sequence_setting, config.sequence_capacity, k,
                double(needed) / (1 << 20), double(available) / (1 << 20));
  return text;
}

}  // namespace markloop::cli
