// CRC-32 (IEEE 802.3, the zlib/PNG one: reflected polynomial 0xEDB88320,
// initial and final XOR 0xFFFFFFFF; check value 0xCBF43926 over "123456789").
#pragma once

#include <array>
#include <cstdint>
#include <span>

namespace markloop::ecu {

namespace detail {
constexpr std::array<std::uint32_t, 256> make_crc32_table() {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t byte = 0; byte < 256; ++byte) {
    std::uint32_t crc = byte;
    for (int bit = 0; bit < 8; ++bit) crc = (crc & 1U) != 0 ? (crc >> 1) ^ 0xEDB88320U : crc >> 1;
    table[byte] = crc;
  }
  return table;
}
inline constexpr std::array<std::uint32_t, 256> kCrc32Table = make_crc32_table();
}  // namespace detail

// Running CRC over pieces fed in order.
class Crc32 {
 public:
  constexpr void add(std::span<const std::uint8_t> bytes) noexcept {
    for (const std::uint8_t b : bytes) state_ = detail::kCrc32Table[(state_ ^ b) & 0xFFU] ^ (state_ >> 8);
  }
  constexpr std::uint32_t value() const noexcept { return state_ ^ 0xFFFFFFFFU; }

 private:
  std::uint32_t state_ = 0xFFFFFFFFU;
};

constexpr std::uint32_t crc32(std::span<const std::uint8_t> bytes) noexcept {
  Crc32 crc;
  crc.add(bytes);
  return crc.value();
}

}  // namespace markloop::ecu
