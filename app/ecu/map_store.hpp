// The place database on disk, so that places are recognised across drives.
//
// File layout (version 1, all integers and floats little-endian):
//   header, 64 bytes:
//     0  magic "MLOOPMAP"           8  u32 version (1)     12 u32 header bytes (64)
//     16 u32 k                      20 u32 landmark record bytes (52)
//     24 u64 landmark count         32 u64 sequence count
//     40 u64 payload bytes          48 u32 payload CRC-32  52..59 zero
//     60 u32 CRC-32 of bytes 0..59
//   payload: the landmarks oldest first (52 bytes each: label u16,
//     observations u16, first_frame u32, last_frame u32, x, y, car_x, car_y,
//     car_yaw f32, has_car_pose u8, facing u8 (0 any, 1 along, 2 against
//     car_yaw; 0 in maps written before it was kept) + 2 zero bytes, t f64,
//     station f64), then
//     the sequences oldest first (k u32 each: landmark index into the above).
//
// The map is the user's data: nothing here ever damages it.
// - Only a regular file is a map. A device node, directory or FIFO is
//   refused before anything is opened for writing; a symbolic link is
//   followed once at start-up, and the map is then read and replaced at the
//   link's target (the link stays a link).
// - One process at a time: loading takes an exclusive lock on PATH.lock for
//   the life of the store; a second one is refused.
// - Saving writes a uniquely named PATH.tmp-XXXXXX in the same directory,
//   fsyncs it, renames it over PATH and fsyncs the directory: a power cut at
//   any point leaves the previous map or the new one, never a mixture.
// - Loading checks everything (size, magic, version, k, checksums, every
//   value and index) before trusting the file; a file that fails is renamed
//   aside to PATH.corrupt-<unix time>[-N], never over an earlier one, and
//   the ECU starts with an empty map. A file that cannot be read, a sound
//   map of another version or k, or one that holds more than the database
//   can, is left alone and the ECU refuses to start (it would overwrite or
//   shrink the map at exit).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <system_error>

#include "app/common/crc32.hpp"
#include "app/common/result.hpp"
#include "app/engine/config.hpp"
#include "app/engine/sequence_database.hpp"
#include "platform/unique_fd.hpp"

namespace markloop::ecu {

inline constexpr std::uint32_t kMapVersion = 1;
inline constexpr std::size_t kMapHeaderBytes = 64;
inline constexpr std::size_t kMapLandmarkBytes = 52;

// kRejected: damaged, set aside, start empty. kUnusable: left untouched,
// do not start (not a regular file, unreadable, locked by another process,
// larger than the database).
enum class MapLoadOutcome : std::uint8_t { kLoaded, kMissing, kRejected, kUnusable };

struct MapLoadResult {
  MapLoadOutcome outcome = MapLoadOutcome::kMissing;
  std::string message;         // what was loaded, or what is wrong with the file
  std::string set_aside_path;  // where a rejected file went (empty if not moved)
  std::size_t landmarks = 0;
  std::size_t sequences = 0;
};

class MapStore {
 public:
  // `path` empty: no map is kept (load finds nothing, save does nothing).
  explicit MapStore(std::string path);

  const std::string& path() const { return path_; }

  // Start-up only (allocates for messages). Locks the map, then fills the
  // empty `database` from the file. Loaded landmarks are moved back in time
  // and distance by more than the match separation, so that they count as an
  // earlier visit.
  MapLoadResult load(SequenceDatabase& database, const MatchConfig& match);

  // Writes the database (no heap: a fixed buffer). Blocking file I/O: call
  // between frames (on command and at shutdown).
  std::error_code save(const SequenceDatabase& database) noexcept;

  std::uint64_t saves() const { return saves_; }
  std::uint64_t save_failures() const { return save_failures_; }

 private:
  std::error_code write_file(const SequenceDatabase& database) noexcept;
  // Resolves a symbolic link, checks the file type and takes the lock; an
  // error says why the map cannot be used.
  Status acquire();
  void set_target(std::string target);
  MapLoadResult reject(const std::string& what);
  MapLoadResult unusable(const std::string& what) const;

  // Loading, step by step: the header's checks, then a pass that verifies
  // the whole payload, then a pass that fills the database.
  MapLoadResult read_file(int fd, SequenceDatabase& database, const MatchConfig& match);
  struct MapHeader {
    std::uint32_t k = 0;
    std::uint64_t landmarks = 0;
    std::uint64_t sequences = 0;
    std::uint32_t payload_crc = 0;
  };
  // Why a file cannot be loaded: kRejected (damaged) or kUnusable (someone's
  // data this ECU must not use or overwrite).
  struct MapFault {
    MapLoadOutcome outcome = MapLoadOutcome::kRejected;
    std::string what;
  };
  MapLoadResult refuse(const MapFault& fault);
  // The header's checks, in the order a broken or foreign file meets them;
  // `bytes` is what could be read of the header.
  static std::optional<MapFault> check_header(std::span<const std::uint8_t> bytes, std::uint64_t file_bytes,
                                              const DatabaseStats& capacity, unsigned database_k,
                                              MapHeader& header);
  // The latest station and time among the file's landmarks.
  struct PayloadExtent {
    double max_station = -1.0e300;
    double max_t = -1.0e300;
  };
  Result<PayloadExtent> verify_payload(int fd, const MapHeader& header);
  Status verify_landmarks(int fd, const MapHeader& header, Crc32& crc, PayloadExtent& extent);
  Status verify_sequences(int fd, const MapHeader& header, Crc32& crc);
  // Loaded landmarks are shifted to before this session; the number of
  // sequences loaded. On error the database is left empty.
  Result<std::size_t> fill_database(int fd, const MapHeader& header, const PayloadExtent& extent,
                                    const MatchConfig& match, SequenceDatabase& database);
  Status load_landmarks(int fd, const MapHeader& header, double station_shift, double time_shift,
                        SequenceDatabase& database);
  Result<std::size_t> load_sequences(int fd, const MapHeader& header, LandmarkId base,
                                     SequenceDatabase& database);
  std::size_t landmarks_per_chunk() const;
  std::size_t sequences_per_chunk(unsigned k) const;

  std::string path_;    // as configured, for messages
  std::string target_;  // the file itself (a link's target)
  std::string temporary_template_;
  std::array<char, 4096> temporary_path_{};
  platform::UniqueFd lock_;
  std::array<std::uint8_t, 1 << 16> buffer_{};
  std::uint64_t saves_ = 0;
  std::uint64_t save_failures_ = 0;
};

}  // namespace markloop::ecu
