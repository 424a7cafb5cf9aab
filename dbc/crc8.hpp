// CRC-8 SAE J1850 as AUTOSAR Crc_CalculateCRC8 computes it: polynomial 0x1D,
// initial value 0xFF, final XOR 0xFF, no reflection. Check value: 0x4B over
// ASCII "123456789".
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

namespace markloop::dbc {

inline constexpr std::uint8_t kCrc8Polynomial = 0x1D;
inline constexpr std::uint8_t kCrc8Initial = 0xFF;
inline constexpr std::uint8_t kCrc8FinalXor = 0xFF;

namespace detail {

constexpr std::array<std::uint8_t, 256> make_crc8_table() {
  std::array<std::uint8_t, 256> table{};
  for (unsigned byte = 0; byte < 256; ++byte) {
    unsigned crc = byte;
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & 0x80U) != 0 ? ((crc << 1) ^ kCrc8Polynomial) : (crc << 1);
    }
    table[byte] = static_cast<std::uint8_t>(crc & 0xFFU);
  }
  return table;
}

inline constexpr std::array<std::uint8_t, 256> kCrc8Table = make_crc8_table();

}  // namespace detail

// Running CRC so that non-contiguous pieces (data id, then payload without
// its CRC byte) can be fed in order without copying.
class Crc8J1850 {
 public:
  constexpr void add(std::uint8_t byte) noexcept { state_ = detail::kCrc8Table[state_ ^ byte]; }
  constexpr void add(std::span<const std::uint8_t> bytes) noexcept {
    for (const std::uint8_t byte : bytes) add(byte);
  }
  constexpr std::uint8_t value() const noexcept { return static_cast<std::uint8_t>(state_ ^ kCrc8FinalXor); }

 private:
  std::uint8_t state_ = kCrc8Initial;
};

constexpr std::uint8_t crc8_j1850(std::span<const std::uint8_t> bytes) noexcept {
  Crc8J1850 crc;
  crc.add(bytes);
  return crc.value();
}

}  // namespace markloop::dbc
