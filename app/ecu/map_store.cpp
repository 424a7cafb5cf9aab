#include "app/ecu/map_store.hpp"

#include <fcntl.h>
#include <sys/stat.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <span>

#include "app/common/crc32.hpp"
#include "platform/files.hpp"
#include "platform/os.hpp"

namespace markloop::ecu {

namespace {

constexpr std::array<std::uint8_t, 8> kMagic{'M', 'L', 'O', 'O', 'P', 'M', 'A', 'P'};

void put16(std::uint8_t* p, std::uint16_t v) {
  p[0] = static_cast<std::uint8_t>(v);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}
void put32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
void put64(std::uint8_t* p, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
void putf(std::uint8_t* p, float v) {
  put32(p, std::bit_cast<std::uint32_t>(v));
}
void putd(std::uint8_t* p, double v) {
  put64(p, std::bit_cast<std::uint64_t>(v));
}
std::uint16_t get16(const std::uint8_t* p) {
  return static_cast<std::uint16_t>(p[0] | (p[1] << 8));
}
std::uint32_t get32(const std::uint8_t* p) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
std::uint64_t get64(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
float getf(const std::uint8_t* p) {
  return std::bit_cast<float>(get32(p));
}
double getd(const std::uint8_t* p) {
  return std::bit_cast<double>(get64(p));
}

void encode_landmark(const Landmark& l, std::uint8_t* p) {
  put16(p + 0, l.label);
  put16(p + 2, l.observations);
  put32(p + 4, l.first_frame);
  put32(p + 8, l.last_frame);
  putf(p + 12, l.x);
  putf(p + 16, l.y);
  putf(p + 20, l.car_x);
  putf(p + 24, l.car_y);
  putf(p + 28, l.car_yaw);
  p[32] = l.has_car_pose ? 1 : 0;
  p[33] = static_cast<std::uint8_t>(l.facing);
  p[34] = p[35] = 0;
  putd(p + 36, l.t);
  putd(p + 44, l.station);
}

// False when a value is not one markloop could have written.
bool decode_landmark(const std::uint8_t* p, Landmark& l) {
  l.label = get16(p + 0);
  l.observations = get16(p + 2);
  l.first_frame = get32(p + 4);
  l.last_frame = get32(p + 8);
  l.x = getf(p + 12);
  l.y = getf(p + 16);
  l.car_x = getf(p + 20);
  l.car_y = getf(p + 24);
  l.car_yaw = getf(p + 28);
  if (p[32] > 1 || p[33] > static_cast<std::uint8_t>(Facing::kAgainst) || p[34] != 0 || p[35] != 0)
    return false;
  l.has_car_pose = p[32] == 1;
  l.facing = static_cast<Facing>(p[33]);
  l.t = getd(p + 36);
  l.station = getd(p + 44);
  const float coordinates[] = {l.x, l.y, l.car_x, l.car_y, l.car_yaw};
  for (const float v : coordinates)
    if (!std::isfinite(v) || std::abs(v) > 1.0e7f) return false;
  return std::isfinite(l.t) && std::isfinite(l.station) && std::abs(l.t) < 1.0e10 &&
         std::abs(l.station) < 1.0e10 && l.first_frame <= l.last_frame;
}

// Fills `buffer` with the payload and hands every full chunk to `flush`.
template <typename Flush>
bool serialise_payload(const SequenceDatabase& database, std::span<std::uint8_t> buffer,
                       std::uint64_t& sequences, Flush&& flush) {
  std::size_t used = 0;
  bool ok = true;
  const auto reserve = [&](std::size_t bytes) -> std::uint8_t* {
    if (used + bytes > buffer.size()) {
      ok = ok && flush(std::span<const std::uint8_t>(buffer.data(), used));
      used = 0;
    }
    std::uint8_t* p = buffer.data() + used;
    used += bytes;
    return p;
  };
  const LandmarkId first = database.first_landmark_id();
  for (LandmarkId id = first; id != database.next_landmark_id(); ++id)
    encode_landmark(*database.landmark(id), reserve(kMapLandmarkBytes));
  sequences = 0;
  const unsigned k = database.k();
  database.for_each_sequence([&](std::span<const LandmarkId> ids) {
    std::uint8_t* p = reserve(4 * k);
    for (unsigned i = 0; i < k; ++i) put32(p + 4 * i, ids[i] - first);
    ++sequences;
  });
  if (used > 0) ok = ok && flush(std::span<const std::uint8_t>(buffer.data(), used));
  return ok;
}

std::string describe(std::error_code ec) {
  return ec.message();
}

const char* file_type_name(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

}  // namespace

MapStore::MapStore(std::string path) : path_(std::move(path)) {
  if (!path_.empty()) set_target(path_);
}

void MapStore::set_target(std::string target) {
  target_ = std::move(target);
  temporary_template_ = target_ + ".tmp-XXXXXX";
}

Status MapStore::acquire() {
  if (lock_) return {};
  struct stat info {};
  if (::lstat(path_.c_str(), &info) == 0 && S_ISLNK(info.st_mode)) {
    char* resolved = ::realpath(path_.c_str(), nullptr);
    if (resolved == nullptr)
      return error("a symbolic link whose target cannot be resolved (" + describe(platform::last_error()) +
                   ")");
    set_target(resolved);
    std::free(resolved);
  }
  if (::stat(target_.c_str(), &info) == 0) {
    if (!S_ISREG(info.st_mode))
      return error(std::string("is ") + file_type_name(info.st_mode) +
                   ", not a map file: refusing to use it");
  } else if (errno != ENOENT) {
    return error("cannot stat: " + describe(platform::last_error()));
  }
  if (temporary_template_.size() >= temporary_path_.size()) return error("path too long");
  const std::string lock_path = target_ + ".lock";
  int fd = -1;
  if (auto ec = platform::sys_open_mode(lock_path.c_str(), O_RDWR | O_CREAT | O_NOFOLLOW, 0644, fd))
    return error("cannot create the lock file " + lock_path + ": " + describe(ec));
  platform::UniqueFd lock(fd);
  if (auto ec = platform::try_lock_exclusive(fd)) {
    if (platform::is_would_block(ec))
      return error("in use by another markloop (" + lock_path + " is locked): one process per map");
    return error("cannot lock " + lock_path + ": " + describe(ec));
  }
  lock_ = std::move(lock);
  return {};
}

std::error_code MapStore::save(const SequenceDatabase& database) noexcept {
  if (path_.empty()) return {};
  std::memcpy(temporary_path_.data(), temporary_template_.c_str(), temporary_template_.size() + 1);
  const std::error_code ec = write_file(database);
  if (ec) {
    ++save_failures_;
    if (std::strcmp(temporary_path_.data(), temporary_template_.c_str()) != 0)
      (void)platform::sys_unlink(temporary_path_.data());
  } else {
    ++saves_;
  }
  return ec;
}

std::error_code MapStore::write_file(const SequenceDatabase& database) noexcept {
  // Pass 1: size and checksum of the payload, without touching the disk.
  Crc32 crc;
  std::uint64_t payload_bytes = 0;
  std::uint64_t sequences = 0;
  serialise_payload(database, buffer_, sequences, [&](std::span<const std::uint8_t> chunk) {
    crc.add(chunk);
    payload_bytes += chunk.size();
    return true;
  });

  std::array<std::uint8_t, kMapHeaderBytes> header{};
  std::copy(kMagic.begin(), kMagic.end(), header.begin());
  put32(&header[8], kMapVersion);
  put32(&header[12], kMapHeaderBytes);
  put32(&header[16], database.k());
  put32(&header[20], kMapLandmarkBytes);
  put64(&header[24], database.next_landmark_id() - database.first_landmark_id());
  put64(&header[32], sequences);
  put64(&header[40], payload_bytes);
  put32(&header[48], crc.value());
  put32(&header[60], crc32(std::span<const std::uint8_t>(header.data(), 60)));

  int fd = -1;
  if (auto ec = platform::create_unique_file(temporary_path_.data(), 0644, fd)) return ec;
  platform::UniqueFd file(fd);
  if (auto ec = platform::write_all(fd, header.data(), header.size())) return ec;
  // Pass 2: the same bytes again, to the file.
  std::error_code write_error;
  std::uint64_t sequences_again = 0;
  serialise_payload(database, buffer_, sequences_again, [&](std::span<const std::uint8_t> chunk) {
    if (!write_error) write_error = platform::write_all(fd, chunk.data(), chunk.size());
    return !write_error;
  });
  if (write_error) return write_error;
  if (auto ec = platform::sys_fsync(fd)) return ec;
  file.reset();
  if (auto ec = platform::sys_rename(temporary_path_.data(), target_.c_str())) return ec;
  return platform::sync_parent_directory(target_.c_str());
}

MapLoadResult MapStore::reject(const std::string& what) {
  MapLoadResult result;
  result.outcome = MapLoadOutcome::kRejected;
  result.message = path_ + ": " + what;
  const std::string base = target_ + ".corrupt-" + std::to_string(std::time(nullptr));
  std::string aside = base;
  std::error_code ec;
  for (int n = 1; n <= 1000; ++n) {
    ec = platform::rename_no_replace(target_.c_str(), aside.c_str());
    if (ec.value() != EEXIST) break;
    aside = base + "-" + std::to_string(n);
  }
  if (ec) {
    result.message += "; could not set it aside: " + describe(ec);
  } else {
    result.set_aside_path = aside;
    result.message += "; set aside as " + aside;
  }
  return result;
}

MapLoadResult MapStore::unusable(const std::string& what) const {
  MapLoadResult result;
  result.outcome = MapLoadOutcome::kUnusable;
  result.message = path_ + ": " + what;
  return result;
}

MapLoadResult MapStore::load(SequenceDatabase& database, const MatchConfig& match) {
  MapLoadResult result;
  if (path_.empty()) {
    result.message = "no map file configured";
    return result;
  }
  if (Status acquired = acquire(); !acquired) return unusable(acquired.message());
  int fd = -1;
  // Non-blocking: a FIFO put in the map's place after acquire() must not
  // hang the open; fstat() below refuses it.
  if (auto ec = platform::sys_open_mode(target_.c_str(), O_RDONLY | O_NONBLOCK, 0, fd)) {
    if (ec.value() == ENOENT) {
      result.message = path_ + ": no map yet, starting empty";
      return result;
    }
    return unusable("cannot open: " + describe(ec) + "; the map is left as it is");
  }
  platform::UniqueFd file(fd);
  return read_file(fd, database, match);
}

MapLoadResult MapStore::refuse(const MapFault& fault) {
  return fault.outcome == MapLoadOutcome::kRejected ? reject(fault.what) : unusable(fault.what);
}

MapLoadResult MapStore::read_file(int fd, SequenceDatabase& database, const MatchConfig& match) {
  struct stat info {};
  if (::fstat(fd, &info) != 0) return unusable("cannot stat: " + describe(platform::last_error()));
  if (!S_ISREG(info.st_mode))
    return unusable(std::string("is ") + file_type_name(info.st_mode) +
                    ", not a map file: refusing to use it");
  std::array<std::uint8_t, kMapHeaderBytes> bytes{};
  std::size_t got = 0;
  if (auto ec = platform::read_full(fd, bytes.data(), bytes.size(), got))
    return reject("read error: " + describe(ec));
  MapHeader header;
  if (std::optional<MapFault> fault =
          check_header(std::span<const std::uint8_t>(bytes.data(), got),
                       static_cast<std::uint64_t>(info.st_size), database.stats(), database.k(), header))
    return refuse(*fault);
  const Result<PayloadExtent> extent = verify_payload(fd, header);
  if (!extent) return reject(extent.message());
  const Result<std::size_t> sequences = fill_database(fd, header, *extent, match, database);
  if (!sequences) return reject(sequences.message());

  MapLoadResult result;
  result.outcome = MapLoadOutcome::kLoaded;
  result.landmarks = database.stats().landmarks;
  result.sequences = *sequences;
  result.message = path_ + ": loaded " + std::to_string(result.landmarks) + " landmarks and " +
                   std::to_string(result.sequences) + " sequences";
  return result;
}

std::optional<MapStore::MapFault> MapStore::check_header(std::span<const std::uint8_t> bytes,
                                                         std::uint64_t file_bytes,
                                                         const DatabaseStats& capacity, unsigned database_k,
                                                         MapHeader& header) {
  const auto damaged = [](std::string what) { return MapFault{MapLoadOutcome::kRejected, std::move(what)}; };
  const auto foreign = [](std::string what) { return MapFault{MapLoadOutcome::kUnusable, std::move(what)}; };
  // Another program's file named by mistake is left alone; a file too short
  // to say what it is counts as damaged.
  if (bytes.size() < 8) return damaged("not a markloop map (too short)");
  if (!std::equal(kMagic.begin(), kMagic.end(), bytes.begin()))
    return foreign("not a markloop map (wrong magic); the file is left as it is: check --map (map.file)");
  if (bytes.size() < kMapHeaderBytes)
    return damaged("truncated header (" + std::to_string(bytes.size()) + " bytes)");
  if (get32(&bytes[60]) != crc32(bytes.first(60))) return damaged("header checksum mismatch");
  // A sound map of another version or k is someone's data, not damage.
  const std::uint32_t version = get32(&bytes[8]);
  if (version != kMapVersion)
    return foreign("map version " + std::to_string(version) + ", this markloop reads version " +
                   std::to_string(kMapVersion) + "; the map is left as it is");
  header.k = get32(&bytes[16]);
  if (get32(&bytes[12]) != kMapHeaderBytes || get32(&bytes[20]) != kMapLandmarkBytes)
    return damaged("unexpected header or record size");
  if (header.k != database_k)
    return foreign("map made with k = " + std::to_string(header.k) +
                   ", this ECU uses k = " + std::to_string(database_k) +
                   "; the map is left as it is (set engine.k to match, or "
                   "use another map file)");
  header.landmarks = get64(&bytes[24]);
  header.sequences = get64(&bytes[32]);
  const std::uint64_t payload_bytes = get64(&bytes[40]);
  header.payload_crc = get32(&bytes[48]);
  if (header.landmarks > (std::uint64_t{1} << 32) || header.sequences > (std::uint64_t{1} << 32) ||
      payload_bytes != header.landmarks * kMapLandmarkBytes + header.sequences * 4 * header.k)
    return damaged("inconsistent counts in header");
  if (header.landmarks > capacity.landmark_capacity || header.sequences > capacity.sequence_capacity)
    return foreign("holds " + std::to_string(header.landmarks) + " landmarks and " +
                   std::to_string(header.sequences) + " sequences; this database holds " +
                   std::to_string(capacity.landmark_capacity) + " landmarks and " +
                   std::to_string(capacity.sequence_capacity) +
                   " sequences (database.landmark_capacity, database.sequence_capacity): it would "
                   "lose places at the next save, so the map is left as it is; raise the capacities");
  if (file_bytes != kMapHeaderBytes + payload_bytes)
    return damaged("size " + std::to_string(file_bytes) + " bytes, header says " +
                   std::to_string(kMapHeaderBytes + payload_bytes) +
                   (file_bytes < kMapHeaderBytes + payload_bytes ? " (truncated)" : ""));
  return std::nullopt;
}

std::size_t MapStore::landmarks_per_chunk() const {
  return buffer_.size() / kMapLandmarkBytes;
}

std::size_t MapStore::sequences_per_chunk(unsigned k) const {
  return buffer_.size() / (4 * std::size_t{k});
}

Result<MapStore::PayloadExtent> MapStore::verify_payload(int fd, const MapHeader& header) {
  // Checksum and every value, before anything enters the database.
  Crc32 crc;
  PayloadExtent extent;
  if (Status landmarks = verify_landmarks(fd, header, crc, extent); !landmarks) return landmarks.error();
  if (Status sequences = verify_sequences(fd, header, crc); !sequences) return sequences.error();
  if (crc.value() != header.payload_crc) return error("payload checksum mismatch");
  return extent;
}

Status MapStore::verify_landmarks(int fd, const MapHeader& header, Crc32& crc, PayloadExtent& extent) {
  Landmark landmark;
  std::size_t got = 0;
  for (std::uint64_t done = 0; done < header.landmarks;) {
    const std::size_t n =
        static_cast<std::size_t>(std::min<std::uint64_t>(header.landmarks - done, landmarks_per_chunk()));
    if (auto ec = platform::read_full(fd, buffer_.data(), n * kMapLandmarkBytes, got))
      return error("read error: " + describe(ec));
    if (got != n * kMapLandmarkBytes) return error("file shrank while reading");
    crc.add(std::span<const std::uint8_t>(buffer_.data(), got));
    for (std::size_t i = 0; i < n; ++i) {
      if (!decode_landmark(&buffer_[i * kMapLandmarkBytes], landmark))
        return error("landmark " + std::to_string(done + i) + " holds impossible values");
      extent.max_station = std::max(extent.max_station, landmark.station);
      extent.max_t = std::max(extent.max_t, landmark.t);
    }
    done += n;
  }
  return {};
}

Status MapStore::verify_sequences(int fd, const MapHeader& header, Crc32& crc) {
  const unsigned k = header.k;
  const std::size_t sequence_bytes = 4 * std::size_t{k};
  std::size_t got = 0;
  for (std::uint64_t done = 0; done < header.sequences;) {
    const std::size_t n =
        static_cast<std::size_t>(std::min<std::uint64_t>(header.sequences - done, sequences_per_chunk(k)));
    if (auto ec = platform::read_full(fd, buffer_.data(), n * sequence_bytes, got))
      return error("read error: " + describe(ec));
    if (got != n * sequence_bytes) return error("file shrank while reading");
    crc.add(std::span<const std::uint8_t>(buffer_.data(), got));
    for (std::size_t i = 0; i < n * k; ++i)
      if (get32(&buffer_[4 * i]) >= header.landmarks)
        return error("sequence " + std::to_string(done + i / k) + " refers to a missing landmark");
    done += n;
  }
  return {};
}

Result<std::size_t> MapStore::fill_database(int fd, const MapHeader& header, const PayloadExtent& extent,
                                            const MatchConfig& match, SequenceDatabase& database) {
  // The file is sound. The old drive ends before the new one starts by more
  // than the match separation in time and distance.
  const bool any = header.landmarks > 0;
  const double station_shift = any ? extent.max_station + match.min_separation_m + 1.0 : 0.0;
  const double time_shift = any ? extent.max_t + match.min_separation_s + 1.0 : 0.0;
  if (::lseek(fd, static_cast<off_t>(kMapHeaderBytes), SEEK_SET) < 0)
    return error("cannot seek: " + describe(platform::last_error()));
  database.clear();
  const LandmarkId base = database.next_landmark_id();
  if (Status landmarks = load_landmarks(fd, header, station_shift, time_shift, database); !landmarks) {
    database.clear();
    return landmarks.error();
  }
  Result<std::size_t> sequences = load_sequences(fd, header, base, database);
  if (!sequences) database.clear();
  return sequences;
}

Status MapStore::load_landmarks(int fd, const MapHeader& header, double station_shift, double time_shift,
                                SequenceDatabase& database) {
  Landmark landmark;
  std::size_t got = 0;
  for (std::uint64_t done = 0; done < header.landmarks;) {
    const std::size_t n =
        static_cast<std::size_t>(std::min<std::uint64_t>(header.landmarks - done, landmarks_per_chunk()));
    if (platform::read_full(fd, buffer_.data(), n * kMapLandmarkBytes, got) || got != n * kMapLandmarkBytes)
      return error("file changed while loading");
    for (std::size_t i = 0; i < n; ++i) {
      decode_landmark(&buffer_[i * kMapLandmarkBytes], landmark);
      landmark.station -= station_shift;
      landmark.t -= time_shift;
      database.add_landmark(landmark);
    }
    done += n;
  }
  return {};
}

Result<std::size_t> MapStore::load_sequences(int fd, const MapHeader& header, LandmarkId base,
                                             SequenceDatabase& database) {
  const unsigned k = header.k;
  const std::size_t sequence_bytes = 4 * std::size_t{k};
  std::array<LandmarkId, kMaxSequenceLength> ids{};
  std::size_t loaded = 0;
  std::size_t got = 0;
  for (std::uint64_t done = 0; done < header.sequences;) {
    const std::size_t n =
        static_cast<std::size_t>(std::min<std::uint64_t>(header.sequences - done, sequences_per_chunk(k)));
    if (platform::read_full(fd, buffer_.data(), n * sequence_bytes, got) || got != n * sequence_bytes)
      return error("file changed while loading");
    for (std::size_t s = 0; s < n; ++s) {
      for (unsigned i = 0; i < k; ++i) ids[i] = base + get32(&buffer_[s * sequence_bytes + 4 * i]);
      // False when the database is smaller than the map and evicted a landmark.
      if (database.add_sequence(std::span<const LandmarkId>(ids.data(), k))) ++loaded;
    }
    done += n;
  }
  return loaded;
}

}  // namespace markloop::ecu
