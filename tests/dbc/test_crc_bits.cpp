// CRC-8 SAE J1850 and DBC bit placement, independent of any message.
#include <array>
#include <cstdint>
#include <span>
#include <string_view>

#include <catch2/catch_test_macros.hpp>

#include "dbc/bits.hpp"
#include "dbc/crc8.hpp"
#include "dbc/e2e.hpp"

using namespace markloop::dbc;

namespace {

template <std::size_t N>
std::uint8_t crc_of(const std::array<std::uint8_t, N>& bytes) {
  return crc8_j1850(std::span<const std::uint8_t>{bytes});
}

}  // namespace

TEST_CASE("CRC-8 SAE J1850 check value over \"123456789\" is 0x4B") {
  constexpr std::string_view text = "123456789";
  std::array<std::uint8_t, 9> bytes{};
  for (std::size_t i = 0; i < text.size(); ++i) bytes[i] = static_cast<std::uint8_t>(text[i]);
  CHECK(crc_of(bytes) == 0x4B);
}

TEST_CASE("CRC-8 SAE J1850 matches the AUTOSAR CRC library's example table") {
  // AUTOSAR SWS CRC Library, Crc_CalculateCRC8 examples (init 0xFF, xor 0xFF).
  CHECK(crc_of(std::array<std::uint8_t, 4>{0x00, 0x00, 0x00, 0x00}) == 0x59);
  CHECK(crc_of(std::array<std::uint8_t, 3>{0xF2, 0x01, 0x83}) == 0x37);
  CHECK(crc_of(std::array<std::uint8_t, 4>{0x0F, 0xAA, 0x00, 0x55}) == 0x79);
  CHECK(crc_of(std::array<std::uint8_t, 4>{0x00, 0xFF, 0x55, 0x11}) == 0xB8);
  CHECK(crc_of(std::array<std::uint8_t, 9>{0x33, 0x22, 0x55, 0xAA, 0xBB, 0xCC, 0xDD, 0xEE, 0xFF}) == 0xCB);
  CHECK(crc_of(std::array<std::uint8_t, 3>{0x92, 0x6B, 0x55}) == 0x8C);
  CHECK(crc_of(std::array<std::uint8_t, 4>{0xFF, 0xFF, 0xFF, 0xFF}) == 0x74);
}

TEST_CASE("CRC-8 by hand for one byte, and of nothing") {
  // 0x00: register 0xFF ^ 0x00 = 0xFF, eight shifts with poly 0x1D give 0xC4;
  // final xor 0xFF -> 0x3B.
  CHECK(crc_of(std::array<std::uint8_t, 1>{0x00}) == 0x3B);
  // 0xFF: register 0xFF ^ 0xFF = 0x00 stays 0x00; xor -> 0xFF.
  CHECK(crc_of(std::array<std::uint8_t, 1>{0xFF}) == 0xFF);
  // Nothing: 0xFF ^ 0xFF.
  CHECK(crc8_j1850({}) == 0x00);
  static_assert(crc8_j1850(std::span<const std::uint8_t>{}) == 0x00, "usable at compile time");
}

TEST_CASE("E2E CRC takes data id low byte, high byte, then payload without the CRC byte") {
  const std::array<std::uint8_t, 4> payload{0xEE, 0x05, 0x02, 0x00};  // byte 0 is the CRC slot
  const std::array<std::uint8_t, 5> sequence{0x02, 0x51, 0x05, 0x02, 0x00};
  CHECK(e2e_crc(0x5102, payload, 0) == crc_of(sequence));
  CHECK(e2e_crc(0x5102, payload, 0) == 0xF9);
  // The CRC byte's content does not matter, the data id does.
  const std::array<std::uint8_t, 4> other_slot{0x11, 0x05, 0x02, 0x00};
  CHECK(e2e_crc(0x5102, other_slot, 0) == 0xF9);
  CHECK(e2e_crc(0x0251, payload, 0) != 0xF9);
}

TEST_CASE("Intel signals: LSB at the start bit, growing into higher bytes") {
  std::array<std::uint8_t, 8> data{};
  constexpr SignalLayout twelve_bits{4, 12, ByteOrder::Intel, false};  // byte 0 bits 4..7, byte 1
  insert(data, twelve_bits, 0xABC);
  CHECK(data == std::array<std::uint8_t, 8>{0xC0, 0xAB, 0, 0, 0, 0, 0, 0});
  CHECK(extract(data, twelve_bits) == 0xABC);
  static_assert(occupied_bits(twelve_bits) == 0xFFF0);
}

TEST_CASE("Motorola signals: MSB at the start bit, continuing at bit 7 of the next byte") {
  std::array<std::uint8_t, 8> data{};
  // Start bit 3 (byte 0 bit 3) and 12 bits: byte 0 bits 3..0 take the top
  // nibble 0xA, byte 1 takes 0xBC.
  constexpr SignalLayout twelve_bits{3, 12, ByteOrder::Motorola, false};
  insert(data, twelve_bits, 0xABC);
  CHECK(data == std::array<std::uint8_t, 8>{0x0A, 0xBC, 0, 0, 0, 0, 0, 0});
  CHECK(extract(data, twelve_bits) == 0xABC);
  static_assert(occupied_bits(twelve_bits) == 0xFF0F);
  // Spanning to the last byte: start 55, 16 bits -> bytes 6 and 7.
  constexpr SignalLayout last_two{55, 16, ByteOrder::Motorola, false};
  static_assert(fits_in(last_two, 8));
  static_assert(!fits_in(last_two, 7));
  // Start 63 (byte 7 bit 7) with 16 bits would run past byte 7.
  static_assert(!fits_in(SignalLayout{63, 16, ByteOrder::Motorola, false}, 8));
  static_assert(!fits_in(SignalLayout{56, 9, ByteOrder::Intel, false}, 8));
}

TEST_CASE("insert leaves neighbouring bits alone; signed values sign-extend") {
  std::array<std::uint8_t, 8> data{};
  data.fill(0xFF);
  constexpr SignalLayout nibble{12, 4, ByteOrder::Intel, true};
  insert(data, nibble, -2);  // 0b1110
  CHECK(data[1] == 0xEF);
  CHECK(extract(data, nibble) == -2);
  insert(data, nibble, 0);
  CHECK(data[1] == 0x0F);
  CHECK(data[0] == 0xFF);
  CHECK(data[2] == 0xFF);
  CHECK(extract(data, SignalLayout{8, 8, ByteOrder::Intel, true}) == 15);
  CHECK(extract(data, SignalLayout{0, 8, ByteOrder::Intel, true}) == -1);
  CHECK(extract(data, SignalLayout{0, 8, ByteOrder::Intel, false}) == 255);
}

TEST_CASE("disjoint detects overlapping layouts") {
  static_assert(disjoint(
      {SignalLayout{0, 8, ByteOrder::Intel, false}, SignalLayout{15, 8, ByteOrder::Motorola, false}}));
  static_assert(!disjoint(
      {SignalLayout{0, 9, ByteOrder::Intel, false}, SignalLayout{15, 8, ByteOrder::Motorola, false}}));
}
