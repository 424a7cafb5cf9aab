// The map file: round trip, and every kind of damage rejected without a crash.
#include <catch2/catch_test_macros.hpp>
#include <catch2/matchers/catch_matchers_string.hpp>

#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <vector>

#include "app/common/crc32.hpp"
#include "app/ecu/map_store.hpp"
#include "app/engine/sequence_database.hpp"

using namespace markloop;
using Catch::Matchers::ContainsSubstring;
namespace fs = std::filesystem;

namespace {

constexpr unsigned kK = 4;

DatabaseConfig small_capacity() {
  DatabaseConfig c;
  c.landmark_capacity = 64;
  c.sequence_capacity = 64;
  return c;
}

// A database with `landmarks` landmarks on a line and every run of k as a sequence.
void fill(SequenceDatabase& db, unsigned landmarks, std::uint32_t seed = 1) {
  std::mt19937 rng(seed);
  std::vector<LandmarkId> ids;
  for (unsigned i = 0; i < landmarks; ++i) {
    Landmark l;
    l.label = static_cast<Label>(rng() % 16);
    l.observations = static_cast<std::uint16_t>(2 + i % 5);
    l.first_frame = 10 * i;
    l.last_frame = 10 * i + 3;
    l.x = static_cast<float>(12.5 * i + static_cast<double>(rng() % 100) * 0.01);
    l.y = static_cast<float>(static_cast<double>(rng() % 100) * 0.03 - 1.5);
    l.car_x = l.x - 10.0f;
    l.car_y = 0.25f;
    l.car_yaw = 0.01f * static_cast<float>(i);
    l.has_car_pose = i % 3 != 0;
    l.facing = static_cast<Facing>(i % 3);
    l.t = 1.25 * i;
    l.station = 12.5 * i;
    ids.push_back(db.add_landmark(l));
    if (ids.size() >= kK) REQUIRE(db.add_sequence(std::span<const LandmarkId>(&ids[ids.size() - kK], kK)));
  }
}

std::string fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("markloop-map-test-" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir.string();
}

std::vector<char> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const std::string& path, const std::vector<char>& bytes, std::size_t count) {
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      .write(bytes.data(), static_cast<std::streamsize>(count));
}

std::size_t files_named(const std::string& dir, const std::string& part) {
  std::size_t n = 0;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.path().filename().string().find(part) != std::string::npos) ++n;
  return n;
}

std::size_t count_set_aside(const std::string& dir) {
  std::size_t n = 0;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.path().filename().string().find(".corrupt-") != std::string::npos) ++n;
  return n;
}

}  // namespace

TEST_CASE("a saved map loads back with the same landmarks and sequences") {
  const std::string dir = fresh_dir("roundtrip");
  const MatchConfig match;
  SequenceDatabase saved(DatabaseConfig{}, match, kK);
  fill(saved, 40);
  ecu::MapStore store(dir + "/map.bin");
  REQUIRE_FALSE(store.save(saved));
  CHECK(store.saves() == 1);
  CHECK(files_named(dir, ".tmp") == 0);

  SequenceDatabase loaded(DatabaseConfig{}, match, kK);
  const ecu::MapLoadResult result = store.load(loaded, match);
  REQUIRE(result.outcome == ecu::MapLoadOutcome::kLoaded);
  CHECK(result.landmarks == 40);
  CHECK(result.sequences == 37);
  CHECK(loaded.stats().sequences == 37);
  // Same landmarks in the same order, moved into the past by more than the separation.
  const double shift_s = 1.25 * 39 + match.min_separation_s + 1.0;
  const double shift_m = 12.5 * 39 + match.min_separation_m + 1.0;
  for (LandmarkId i = 0; i < 40; ++i) {
    const Landmark& a = *saved.landmark(saved.first_landmark_id() + i);
    const Landmark& b = *loaded.landmark(loaded.first_landmark_id() + i);
    CHECK(a.label == b.label);
    CHECK(a.x == b.x);
    CHECK(a.y == b.y);
    CHECK(a.car_yaw == b.car_yaw);
    CHECK(a.has_car_pose == b.has_car_pose);
    CHECK(a.facing == b.facing);
    CHECK(a.last_frame == b.last_frame);
    CHECK(b.t == a.t - shift_s);
    CHECK(b.station == a.station - shift_m);
  }
  // The loaded index finds a stored sequence by its shape.
  SequenceShape shape;
  std::array<LandmarkId, kK> ids{};
  for (unsigned i = 0; i < kK; ++i) ids[i] = loaded.first_landmark_id() + 10 + i;
  REQUIRE(loaded.shape_of(ids, shape));
  bool limited = false;
  CHECK(loaded.for_each_match(shape, 8, limited, [](auto) { return true; }) >= 1);
}

TEST_CASE("an empty map and a missing file") {
  const std::string dir = fresh_dir("empty");
  const MatchConfig match;
  SequenceDatabase db(small_capacity(), match, kK);
  ecu::MapStore store(dir + "/map.bin");
  CHECK(store.load(db, match).outcome == ecu::MapLoadOutcome::kMissing);
  REQUIRE_FALSE(store.save(db));
  const auto result = store.load(db, match);
  CHECK(result.outcome == ecu::MapLoadOutcome::kLoaded);
  CHECK(result.landmarks == 0);
  ecu::MapStore none("");
  CHECK(none.load(db, match).outcome == ecu::MapLoadOutcome::kMissing);
  CHECK_FALSE(none.save(db));
}

TEST_CASE("a map larger than the database is refused, naming both sizes, and left untouched") {
  const std::string dir = fresh_dir("larger");
  const MatchConfig match;
  SequenceDatabase big(DatabaseConfig{}, match, kK);
  fill(big, 200);
  const std::string path = dir + "/map.bin";
  {
    ecu::MapStore store(path);
    REQUIRE_FALSE(store.save(big));
  }
  const std::vector<char> before = read_bytes(path);
  SequenceDatabase small(small_capacity(), match, kK);
  ecu::MapStore store(path);
  const auto result = store.load(small, match);
  REQUIRE(result.outcome == ecu::MapLoadOutcome::kUnusable);
  CHECK_THAT(result.message, ContainsSubstring("holds 200 landmarks and 197 sequences"));
  CHECK_THAT(result.message, ContainsSubstring("this database holds 64 landmarks and 64 sequences"));
  CHECK(small.stats().landmarks == 0);
  CHECK(read_bytes(path) == before);
  CHECK(count_set_aside(dir) == 0);
}

TEST_CASE("a map truncated at every byte is rejected, set aside, and leaves an empty database") {
  const std::string dir = fresh_dir("truncated");
  const MatchConfig match;
  SequenceDatabase saved(small_capacity(), match, kK);
  fill(saved, 6);  // 64 + 6*52 + 3*16 = 424 bytes
  const std::string path = dir + "/map.bin";
  ecu::MapStore store(path);
  REQUIRE_FALSE(store.save(saved));
  const std::vector<char> bytes = read_bytes(path);
  REQUIRE(bytes.size() == ecu::kMapHeaderBytes + 6 * ecu::kMapLandmarkBytes + 3 * 4 * kK);
  for (std::size_t length = 0; length < bytes.size(); ++length) {
    write_bytes(path, bytes, length);
    SequenceDatabase db(small_capacity(), match, kK);
    const auto result = store.load(db, match);
    INFO("length " << length << ": " << result.message);
    REQUIRE(result.outcome == ecu::MapLoadOutcome::kRejected);
    REQUIRE_FALSE(result.set_aside_path.empty());
    REQUIRE_FALSE(fs::exists(path));
    REQUIRE(db.stats().landmarks == 0);
    REQUIRE(db.stats().sequences == 0);
  }
  CHECK(count_set_aside(dir) >= 1);
  // Trailing garbage is damage too.
  std::vector<char> longer = bytes;
  longer.push_back('x');
  write_bytes(path, longer, longer.size());
  SequenceDatabase db(small_capacity(), match, kK);
  CHECK(store.load(db, match).outcome == ecu::MapLoadOutcome::kRejected);
}

TEST_CASE("every single flipped bit is detected") {
  const std::string dir = fresh_dir("flipped");
  const MatchConfig match;
  SequenceDatabase saved(small_capacity(), match, kK);
  fill(saved, 5);
  const std::string path = dir + "/map.bin";
  ecu::MapStore store(path);
  REQUIRE_FALSE(store.save(saved));
  const std::vector<char> bytes = read_bytes(path);
  for (std::size_t bit = 0; bit < 8 * bytes.size(); ++bit) {
    std::vector<char> damaged = bytes;
    damaged[bit / 8] = static_cast<char>(damaged[bit / 8] ^ (1 << (bit % 8)));
    write_bytes(path, damaged, damaged.size());
    SequenceDatabase db(small_capacity(), match, kK);
    const auto result = store.load(db, match);
    INFO("bit " << bit << ": " << result.message);
    // A flipped bit in the magic makes another program's file: left alone.
    REQUIRE(result.outcome == (bit < 64 ? ecu::MapLoadOutcome::kUnusable : ecu::MapLoadOutcome::kRejected));
    REQUIRE(db.stats().landmarks == 0);
  }
}

TEST_CASE("foreign files, other versions and another k are refused and left alone") {
  const std::string dir = fresh_dir("foreign");
  const std::string path = dir + "/map.bin";
  const MatchConfig match;
  ecu::MapStore store(path);
  SequenceDatabase db(small_capacity(), match, kK);

  std::ofstream(path) << "# markloop.conf\ncamera.device = /dev/video0\n" << std::string(200, '#');
  const std::vector<char> foreign = read_bytes(path);
  auto result = store.load(db, match);
  CHECK(result.outcome == ecu::MapLoadOutcome::kUnusable);
  CHECK_THAT(result.message, ContainsSubstring("wrong magic"));
  CHECK(read_bytes(path) == foreign);
  CHECK(count_set_aside(dir) == 0);

  // Version 2 with a correct header checksum: the version is what is reported.
  SequenceDatabase saved(small_capacity(), match, kK);
  fill(saved, 5);
  REQUIRE_FALSE(store.save(saved));
  std::vector<char> bytes = read_bytes(path);
  bytes[8] = 2;
  std::array<std::uint8_t, 60> header{};
  std::copy_n(bytes.begin(), 60, header.begin());
  const std::uint32_t crc = ecu::crc32(header);
  for (int i = 0; i < 4; ++i) bytes[60 + i] = static_cast<char>(crc >> (8 * i));
  write_bytes(path, bytes, bytes.size());
  result = store.load(db, match);
  CHECK(result.outcome == ecu::MapLoadOutcome::kUnusable);  // sound, but not ours to read: left alone
  CHECK_THAT(result.message, ContainsSubstring("map version 2"));
  CHECK(read_bytes(path) == bytes);

  // Made with another k: left alone too.
  REQUIRE_FALSE(store.save(saved));
  const std::vector<char> saved_bytes = read_bytes(path);
  SequenceDatabase other_k(small_capacity(), match, 5);
  result = store.load(other_k, match);
  CHECK(result.outcome == ecu::MapLoadOutcome::kUnusable);
  CHECK_THAT(result.message, ContainsSubstring("k = 4, this ECU uses k = 5"));
  CHECK(read_bytes(path) == saved_bytes);
}

TEST_CASE("a map with several faults is judged by the first header check it fails") {
  const std::string dir = fresh_dir("several_faults");
  const std::string path = dir + "/map.bin";
  const MatchConfig match;
  ecu::MapStore store(path);
  SequenceDatabase saved(small_capacity(), match, kK);
  fill(saved, 5);
  const auto with_header_crc = [](std::vector<char> bytes) {
    std::array<std::uint8_t, 60> header{};
    std::copy_n(bytes.begin(), 60, header.begin());
    const std::uint32_t crc = ecu::crc32(header);
    for (int i = 0; i < 4; ++i) bytes[60 + i] = static_cast<char>(crc >> (8 * i));
    return bytes;
  };

  // Another version and k: the version is checked first.
  REQUIRE_FALSE(store.save(saved));
  std::vector<char> bytes = read_bytes(path);
  bytes[8] = 2;
  bytes[16] = 5;
  bytes = with_header_crc(bytes);
  write_bytes(path, bytes, bytes.size());
  SequenceDatabase db(small_capacity(), match, kK);
  auto result = store.load(db, match);
  CHECK(result.outcome == ecu::MapLoadOutcome::kUnusable);
  CHECK_THAT(result.message, ContainsSubstring("map version 2"));
  CHECK(read_bytes(path) == bytes);

  // Another k and a wrong size: the k comes first, and the file is left alone.
  REQUIRE_FALSE(store.save(saved));
  bytes = read_bytes(path);
  bytes[16] = 5;
  bytes = with_header_crc(bytes);
  write_bytes(path, bytes, bytes.size() - 1);
  result = store.load(db, match);
  CHECK(result.outcome == ecu::MapLoadOutcome::kUnusable);
  CHECK_THAT(result.message, ContainsSubstring("k = 5, this ECU uses k = 4"));
  CHECK(count_set_aside(dir) == 0);

  // Another version behind a broken header checksum: damaged, set aside.
  REQUIRE_FALSE(store.save(saved));
  bytes = read_bytes(path);
  bytes[8] = 2;
  write_bytes(path, bytes, bytes.size());
  result = store.load(db, match);
  CHECK(result.outcome == ecu::MapLoadOutcome::kRejected);
  CHECK_THAT(result.message, ContainsSubstring("header checksum mismatch"));
  CHECK(count_set_aside(dir) == 1);
  CHECK(db.stats().landmarks == 0);
}

TEST_CASE("a failed save leaves the previous map intact and no temporary behind") {
  const std::string dir = fresh_dir("atomic");
  const std::string path = dir + "/map.bin";
  const MatchConfig match;
  SequenceDatabase first(small_capacity(), match, kK);
  fill(first, 8);
  ecu::MapStore store(path);
  REQUIRE_FALSE(store.save(first));
  const std::vector<char> before = read_bytes(path);

  // A power cut mid-save leaves a partial temporary file: it is never read.
  write_bytes(path + ".tmp-ABCDEF", before, before.size() / 2);
  SequenceDatabase db(small_capacity(), match, kK);
  CHECK(store.load(db, match).outcome == ecu::MapLoadOutcome::kLoaded);
  fs::remove(path + ".tmp-ABCDEF");

  // The disk fills up mid-save (a file size limit stands in for it, root or not).
  SequenceDatabase second(small_capacity(), match, kK);
  fill(second, 20, 7);
  struct sigaction ignore {
  }, previous{};
  ignore.sa_handler = SIG_IGN;
  REQUIRE(::sigaction(SIGXFSZ, &ignore, &previous) == 0);
  rlimit limit{}, saved_limit{};
  REQUIRE(::getrlimit(RLIMIT_FSIZE, &saved_limit) == 0);
  limit = saved_limit;
  limit.rlim_cur = 256;
  REQUIRE(::setrlimit(RLIMIT_FSIZE, &limit) == 0);
  const std::error_code failed = store.save(second);
  ::setrlimit(RLIMIT_FSIZE, &saved_limit);
  ::sigaction(SIGXFSZ, &previous, nullptr);
  CHECK(failed);
  CHECK(store.save_failures() == 1);
  CHECK(read_bytes(path) == before);
  CHECK(files_named(dir, ".tmp") == 0);
}

TEST_CASE("what is not a regular file is never a map, and is left as it is") {
  const std::string dir = fresh_dir("not-regular");
  const MatchConfig match;
  const auto refused = [&](const std::string& path, const char* kind) {
    SequenceDatabase db(small_capacity(), match, kK);
    ecu::MapStore store(path);
    const auto result = store.load(db, match);
    INFO(result.message);
    CHECK(result.outcome == ecu::MapLoadOutcome::kUnusable);
    CHECK_THAT(result.message, ContainsSubstring(kind));
  };
  fs::create_directory(dir + "/directory");
  refused(dir + "/directory", "is a directory");
  REQUIRE(::mkfifo((dir + "/fifo").c_str(), 0644) == 0);
  refused(dir + "/fifo", "is a FIFO");  // and does not wait for a writer
  fs::create_symlink("/dev/null", dir + "/device");
  refused(dir + "/device", "is a character device");
  CHECK(fs::is_character_file("/dev/null"));
  CHECK(fs::is_directory(dir + "/directory"));
  CHECK(fs::is_fifo(dir + "/fifo"));
  CHECK(count_set_aside(dir) == 0);
}

TEST_CASE("a map behind a symbolic link is read and replaced at the link's target") {
  const std::string dir = fresh_dir("symlink");
  const MatchConfig match;
  fs::create_directories(dir + "/storage");
  SequenceDatabase saved(small_capacity(), match, kK);
  fill(saved, 8);
  {
    ecu::MapStore target(dir + "/storage/map.bin");
    REQUIRE_FALSE(target.save(saved));
  }
  fs::create_symlink("storage/map.bin", dir + "/map.bin");
  SequenceDatabase db(small_capacity(), match, kK);
  {
    ecu::MapStore store(dir + "/map.bin");
    REQUIRE(store.load(db, match).outcome == ecu::MapLoadOutcome::kLoaded);
    SequenceDatabase more(small_capacity(), match, kK);
    fill(more, 12, 3);
    REQUIRE_FALSE(store.save(more));
    CHECK(fs::is_symlink(dir + "/map.bin"));
    CHECK(fs::exists(dir + "/storage/map.bin.lock"));
  }
  SequenceDatabase reloaded(small_capacity(), match, kK);
  ecu::MapStore again(dir + "/storage/map.bin");
  CHECK(again.load(reloaded, match).landmarks == 12);
  // A link to nothing is refused rather than replaced by a file.
  fs::create_symlink("storage/none.bin", dir + "/dangling.bin");
  ecu::MapStore dangling(dir + "/dangling.bin");
  CHECK(dangling.load(db, match).outcome == ecu::MapLoadOutcome::kUnusable);
  CHECK(fs::is_symlink(dir + "/dangling.bin"));
}

TEST_CASE("one process per map: a second store on the same map is refused") {
  const std::string dir = fresh_dir("locked");
  const MatchConfig match;
  SequenceDatabase db(small_capacity(), match, kK);
  ecu::MapStore first(dir + "/map.bin");
  REQUIRE(first.load(db, match).outcome == ecu::MapLoadOutcome::kMissing);
  ecu::MapStore second(dir + "/map.bin");
  const auto result = second.load(db, match);
  CHECK(result.outcome == ecu::MapLoadOutcome::kUnusable);
  CHECK_THAT(result.message, ContainsSubstring("in use by another markloop"));
  // Saves of the holder use temporaries of their own name.
  fill(db, 6);
  REQUIRE_FALSE(first.save(db));
  REQUIRE_FALSE(first.save(db));
  CHECK(files_named(dir, ".tmp") == 0);
}

TEST_CASE("damaged maps set aside in the same second never overwrite each other") {
  const std::string dir = fresh_dir("aside");
  const MatchConfig match;
  const std::string path = dir + "/map.bin";
  for (int i = 0; i < 3; ++i) {
    std::ofstream(path) << "MLOOPMAP, cut short " << i;
    SequenceDatabase db(small_capacity(), match, kK);
    ecu::MapStore store(path);
    CHECK(store.load(db, match).outcome == ecu::MapLoadOutcome::kRejected);
  }
  CHECK(count_set_aside(dir) == 3);
}
