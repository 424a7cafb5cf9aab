// Inputs read within bounds, streams whose waits end on a stop request, and
// outputs replaced whole.
#include <catch2/catch_test_macros.hpp>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <filesystem>
#include <fstream>
#include <string>

#include "platform/files.hpp"
#include "platform/syscall.hpp"

using namespace markloop;
namespace fs = std::filesystem;

namespace {

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("markloop-files-test-" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::string slurp(const fs::path& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

TEST_CASE("read_file_bounded reads up to its limit and names what it refuses") {
  const fs::path dir = fresh_dir("bounded");
  std::string text;
  std::ofstream(dir / "ten") << "0123456789";
  CHECK_FALSE(platform::read_file_bounded((dir / "ten").c_str(), 10, text));
  CHECK(text == "0123456789");
  CHECK(platform::read_file_bounded((dir / "ten").c_str(), 9, text).value() == EFBIG);
  CHECK(text.empty());
  // A device that never ends stops at the limit instead of growing the reader.
  CHECK(platform::read_file_bounded("/dev/zero", 1 << 20, text).value() == EFBIG);
  CHECK(platform::read_file_bounded(dir.c_str(), 1 << 20, text).value() == EISDIR);
  CHECK(platform::read_file_bounded((dir / "none").c_str(), 1 << 20, text).value() == ENOENT);
  // A FIFO is read as its writer writes, and refused where it would be read twice.
  REQUIRE(::mkfifo((dir / "fifo").c_str(), 0644) == 0);
  CHECK(platform::refuse_pipe((dir / "fifo").c_str()).value() == ESPIPE);
  CHECK_FALSE(platform::refuse_pipe((dir / "ten").c_str()));

  const auto message = [](std::error_code ec) {
    return platform::describe_read_error("F", ec, 1 << 20, "a configuration file");
  };
  CHECK(message(platform::make_error(EFBIG)) == "F: larger than 1 MiB, the limit for a configuration file");
  CHECK(message(platform::make_error(EISDIR)) == "F: is a directory, not a configuration file");
  CHECK(message(platform::make_error(ENOENT)) == "F: cannot open: No such file or directory");
  CHECK(message(platform::make_error(ESPIPE)) ==
        "F: is a pipe or socket, not a configuration file (it is read more than once: give a file)");
}

TEST_CASE("InputStream reads a pipe in order and a stop request ends a wait for data") {
  int data[2], stop[2];
  REQUIRE(::pipe(data) == 0);
  REQUIRE(::pipe(stop) == 0);
  REQUIRE(::write(data[1], "abcdef", 6) == 6);
  platform::InputStream in;
  REQUIRE_FALSE(in.open(("/dev/fd/" + std::to_string(data[0])).c_str()));
  in.set_stop_fd(stop[0]);
  char buffer[4] = {};
  std::size_t got = 0;
  CHECK(in.read(buffer, 4, got) == platform::InputStream::Status::kOk);
  CHECK(std::string(buffer, 4) == "abcd");
  CHECK(in.read(nullptr, 1, got) == platform::InputStream::Status::kOk);  // skipped
  char c = 0;
  CHECK(in.get(c) == platform::InputStream::Status::kOk);
  CHECK(c == 'f');
  CHECK(in.offset() == 6);
  REQUIRE(::write(stop[1], "x", 1) == 1);
  CHECK(in.get(c) == platform::InputStream::Status::kStopped);
  ::close(data[1]);
  REQUIRE(::read(stop[0], buffer, 1) == 1);  // the stop is handled: the writer's end is
  CHECK(in.get(c) == platform::InputStream::Status::kEnd);
  ::close(data[0]);
  ::close(stop[0]);
  ::close(stop[1]);

  platform::InputStream directory;
  CHECK(directory.open(fs::temp_directory_path().c_str()).value() == EISDIR);
}

TEST_CASE("write_file_replacing replaces a file whole and reports what it cannot write") {
  const fs::path dir = fresh_dir("replacing");
  const fs::path path = dir / "summary.json";
  std::ofstream(path) << "old";
  CHECK_FALSE(platform::write_file_replacing(path.c_str(), "new"));
  CHECK(slurp(path) == "new");
  std::size_t entries = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir)) ++entries;
  CHECK(entries == 1);  // no temporary left behind
  CHECK(platform::write_file_replacing(dir.c_str(), "x").value() == EISDIR);
  CHECK(platform::write_file_replacing("/dev/full", "x").value() == ENOSPC);
  CHECK_FALSE(platform::write_file_replacing("/dev/null", "x"));
  CHECK(fs::is_character_file("/dev/null"));
}

TEST_CASE("rename_no_replace never overwrites, and unique files never collide") {
  const fs::path dir = fresh_dir("no-replace");
  std::ofstream(dir / "a") << "a";
  std::ofstream(dir / "b") << "b";
  CHECK(platform::rename_no_replace((dir / "a").c_str(), (dir / "b").c_str()).value() == EEXIST);
  CHECK(slurp(dir / "b") == "b");
  CHECK_FALSE(platform::rename_no_replace((dir / "a").c_str(), (dir / "c").c_str()));
  CHECK(slurp(dir / "c") == "a");

  std::string first = (dir / "t-XXXXXX").string(), second = first;
  int fd1 = -1, fd2 = -1;
  REQUIRE_FALSE(platform::create_unique_file(first.data(), 0644, fd1));
  REQUIRE_FALSE(platform::create_unique_file(second.data(), 0644, fd2));
  CHECK(first != second);
  ::close(fd1);
  ::close(fd2);
}

TEST_CASE("an exclusive lock is refused to a second holder until the first lets go") {
  const fs::path dir = fresh_dir("lock");
  const std::string path = (dir / "map.lock").string();
  const int first = ::open(path.c_str(), O_RDWR | O_CREAT, 0644);
  const int second = ::open(path.c_str(), O_RDWR);
  REQUIRE(first >= 0);
  REQUIRE(second >= 0);
  CHECK_FALSE(platform::try_lock_exclusive(first));
  CHECK(platform::is_would_block(platform::try_lock_exclusive(second)));
  ::close(first);
  CHECK_FALSE(platform::try_lock_exclusive(second));
  ::close(second);
  CHECK(platform::available_memory_bytes() > 0);
}
