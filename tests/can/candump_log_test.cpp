#include <catch2/catch_test_macros.hpp>

#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <string>

#include "drivers/can/candump_log.hpp"

using namespace markloop::can;

namespace {

CanFrame make(std::uint32_t id, bool ext, std::initializer_list<std::uint8_t> bytes, std::int64_t ts = 0) {
  CanFrame f;
  f.id = id;
  f.extended = ext;
  f.dlc = static_cast<std::uint8_t>(bytes.size());
  std::size_t i = 0;
  for (auto b : bytes) f.data[i++] = b;
  f.timestamp_ns = ts;
  return f;
}

std::string temp_path(const char* name) {
  return std::string(P_tmpdir) + "/markloop-" + std::to_string(::getpid()) + "-" + name;
}

std::string line_of(const CanFrame& f, std::string_view iface = "vcan0") {
  char buf[kCandumpMaxLine];
  const std::size_t n = format_candump_line(f, iface, buf, sizeof(buf));
  return std::string(buf, n);
}

std::string parse_error(std::string_view line) {
  CandumpRecord r;
  CandumpLineError e;
  if (parse_candump_line(line, r, e)) return "ok";
  return std::to_string(e.column) + ":" + e.what;
}

}  // namespace

TEST_CASE("candump lines are formatted like candump -l") {
  CHECK(line_of(make(0x123, false, {0xDE, 0xAD, 0xBE, 0xEF}, 1700000000123456000)) ==
        "(1700000000.123456) vcan0 123#DEADBEEF\n");
  CHECK(line_of(make(0x18FF0001, true, {0x01, 0x02}, 5'000'001'000)) ==
        "(0000000005.000001) vcan0 18FF0001#0102\n");
  CHECK(line_of(make(0x7, false, {}, 1'000'000'000), "can1") == "(0000000001.000000) can1 007#\n");
  CHECK(line_of(make(0x800, false, {1})).empty());      // id too large for standard
  CHECK(line_of(make(0x20000000, true, {1})).empty());  // id too large for extended
  CHECK(line_of(make(0x1, false, {1}), "").empty());
  CHECK(line_of(make(0x1, false, {1}), "has space").empty());
  CanFrame bad = make(0x1, false, {});
  bad.dlc = 9;
  CHECK(line_of(bad).empty());
}

TEST_CASE("candump lines parse back to the same frame") {
  CandumpRecord r;
  CandumpLineError e;
  REQUIRE(parse_candump_line("(1700000000.123456) vcan0 123#DEADBEEF", r, e));
  CHECK(r.frame.id == 0x123);
  CHECK_FALSE(r.frame.extended);
  CHECK(r.frame.dlc == 4);
  CHECK(r.frame.data[0] == 0xDE);
  CHECK(r.frame.data[3] == 0xEF);
  CHECK(r.frame.timestamp_ns == 1700000000123456000);
  CHECK(r.interface_name() == "vcan0");

  REQUIRE(parse_candump_line("(0.000001) can0 1FFFFFFF#", r, e));
  CHECK(r.frame.extended);
  CHECK(r.frame.id == 0x1FFFFFFF);
  CHECK(r.frame.dlc == 0);
  CHECK(r.frame.timestamp_ns == 1000);

  REQUIRE(parse_candump_line("(1.000000) can0 00000123#0102030405060708 R", r, e));
  CHECK(r.frame.extended);
  CHECK(r.frame.id == 0x123);
  CHECK(r.frame.dlc == 8);
  REQUIRE(parse_candump_line("(1.000000) can0 7ff#abcdef", r, e));  // lowercase accepted
  CHECK(r.frame.id == 0x7FF);
  CHECK(r.frame.data[2] == 0xEF);
  REQUIRE(parse_candump_line("(9223372035.999999) can0 7ff#abcdef", r, e));  // the latest time
  CHECK(r.frame.timestamp_ns == 9'223'372'035'999'999'000);
}

TEST_CASE("bad candump lines say where and what") {
  CHECK(parse_error("") == "1:empty line");
  CHECK(parse_error("1700000000.123456) vcan0 123#00") == "1:expected '(' starting the timestamp");
  CHECK(parse_error("(1700000000.12345) vcan0 123#00") ==
        "18:timestamp needs exactly 6 digits of microseconds");
  CHECK(parse_error("(1700000000.1234567) vcan0 123#00") == "19:expected ')' after 6 digits of microseconds");
  CHECK(parse_error("(x.123456) vcan0 123#00") == "2:expected timestamp seconds (digits)");
  // Found by the fuzz target: nanoseconds past 2^63 overflowed.
  CHECK(parse_error("(17000000011.000000) vcan0 123#00") == "12:timestamp seconds too long");
  CHECK(parse_error("(9223372036.000000) vcan0 123#00") == "2:timestamp seconds beyond the year 2262");
  CHECK(parse_error("(1.123456)  vcan0 123#00") == "12:missing interface name");
  CHECK(parse_error("(1.123456) vcan0") == "17:expected ' ID#DATA' after the interface name");
  CHECK(parse_error("(1.123456) vcan0 12#00") ==
        "18:CAN id must have 3 (standard) or 8 (extended) hex digits");
  CHECK(parse_error("(1.123456) vcan0 800#00") == "18:standard CAN id above 0x7FF");
  CHECK(parse_error("(1.123456) vcan0 20000004#0000000000000000") == "18:error frames are not supported");
  CHECK(parse_error("(1.123456) vcan0 12G#00") == "20:bad character in the CAN id (hex digits expected)");
  CHECK(parse_error("(1.123456) vcan0 123") == "21:missing '#' after the CAN id");
  CHECK(parse_error("(1.123456) vcan0 123#ABC") == "24:odd number of hex digits in the data");
  CHECK(parse_error("(1.123456) vcan0 123#0102030405060708FF") == "38:more than 8 data bytes");
  CHECK(parse_error("(1.123456) vcan0 123#R") == "22:remote (RTR) frames are not supported");
  CHECK(parse_error("(1.123456) vcan0 123##1AB") == "22:CAN FD frames are not supported");
  CHECK(parse_error("(1.123456) vcan0 123#0G") == "23:bad character in the data (hex digits expected)");
  CHECK(parse_error("(1.123456) vcan0 123#00 X") == "24:unexpected text after the data");
  CHECK(parse_error("(1.123456) vcan0 123#00\r") == "24:bad character in the data (hex digits expected)");
}

TEST_CASE("candump log writer and reader round trip through a file") {
  const std::string path = temp_path("roundtrip.log");
  std::vector<CanFrame> frames;
  for (std::uint32_t i = 0; i < 500; ++i) {
    CanFrame f;
    f.extended = (i % 3) == 0;
    f.id = f.extended ? (0x18DA0000U + i) : (i * 7U) % 0x800U;
    f.dlc = static_cast<std::uint8_t>(i % 9);
    for (std::uint8_t b = 0; b < f.dlc; ++b) f.data[b] = static_cast<std::uint8_t>(i * 31 + b * 17);
    f.timestamp_ns = 1700000000'000000000LL + static_cast<std::int64_t>(i) * 1'000'000 + 123'000;
    frames.push_back(f);
  }
  {
    CandumpLogWriter writer;
    REQUIRE_FALSE(writer.open(path.c_str(), "vcan0"));
    CanFrameSink& sink = writer;  // the application writes through the interface
    for (const auto& f : frames) REQUIRE_FALSE(sink.send(f));
    CanFrame bad;
    bad.dlc = 9;
    CHECK(sink.send(bad) == std::errc::invalid_argument);
    CHECK(writer.frames_written() == frames.size());
    REQUIRE_FALSE(writer.close());
    REQUIRE_FALSE(writer.close());  // twice is fine
    CHECK(sink.send(frames[0]) == std::errc::not_connected);
  }
  CandumpLogReader reader;
  REQUIRE_FALSE(reader.open(path));
  CandumpRecord rec;
  for (const auto& f : frames) {
    REQUIRE(reader.next(rec) == CandumpLogReader::Status::Frame);
    CHECK(same_content(rec.frame, f));
    CHECK(rec.frame.timestamp_ns == f.timestamp_ns);
    CHECK(rec.interface_name() == "vcan0");
  }
  CHECK(reader.next(rec) == CandumpLogReader::Status::End);
  std::remove(path.c_str());
}

TEST_CASE("the writer stamps frames without a timestamp with the current time") {
  const std::string path = temp_path("stamp.log");
  CandumpLogWriter writer;
  REQUIRE_FALSE(writer.open(path.c_str(), "can0"));
  REQUIRE_FALSE(writer.send(make(0x100, false, {1, 2, 3})));
  REQUIRE_FALSE(writer.close());
  CandumpLogReader reader;
  REQUIRE_FALSE(reader.open(path));
  CandumpRecord rec;
  REQUIRE(reader.next(rec) == CandumpLogReader::Status::Frame);
  CHECK(rec.frame.timestamp_ns > 1600000000'000000000LL);
  std::remove(path.c_str());
}

TEST_CASE("the reader reports file:line:column on the first bad line and stops") {
  const std::string path = temp_path("bad.log");
  {
    std::ofstream out(path);
    out << "(1700000000.000001) vcan0 123#01\n"
        << "(1700000000.000002) vcan0 124#0203\n"
        << "(1700000000.000003) vcan0 125#0\n"
        << "(1700000000.000004) vcan0 126#04\n";
  }
  CandumpLogReader reader;
  REQUIRE_FALSE(reader.open(path));
  CandumpRecord rec;
  REQUIRE(reader.next(rec) == CandumpLogReader::Status::Frame);
  REQUIRE(reader.next(rec) == CandumpLogReader::Status::Frame);
  REQUIRE(reader.next(rec) == CandumpLogReader::Status::Error);
  CHECK(reader.error() == path +
                              ":3:31: odd number of hex digits in the data in "
                              "'(1700000000.000003) vcan0 125#0'");
  CHECK(reader.next(rec) == CandumpLogReader::Status::Error);
  std::remove(path.c_str());

  CHECK(reader.open(path + ".does-not-exist") == std::errc::no_such_file_or_directory);
}

TEST_CASE("the reader takes a log from a pipe, and a stop request ends a wait for its next line") {
  int fds[2], stop[2];
  REQUIRE(::pipe(fds) == 0);
  REQUIRE(::pipe(stop) == 0);
  const std::string lines = "(0000000000.020000) vcan0 120#01\n(0000000000.040000) vc";
  REQUIRE(::write(fds[1], lines.data(), lines.size()) == static_cast<ssize_t>(lines.size()));
  CandumpLogReader reader;
  REQUIRE_FALSE(reader.open("/dev/fd/" + std::to_string(fds[0])));
  reader.set_stop_fd(stop[0]);
  CandumpRecord rec;
  REQUIRE(reader.next(rec) == CandumpLogReader::Status::Frame);
  CHECK(rec.frame.timestamp_ns == 20'000'000);
  REQUIRE(::write(stop[1], "x", 1) == 1);  // half a line in, the writer stalls
  CHECK(reader.next(rec) == CandumpLogReader::Status::Stopped);
  ::close(fds[1]);
  ::close(stop[0]);
  ::close(stop[1]);
  reader.close();
  ::close(fds[0]);
  CHECK(reader.open("/tmp").value() == EISDIR);
}
