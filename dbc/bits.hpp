// Placing DBC signals into classic CAN payloads (at most 8 bytes).
//
// DBC bit numbering: bit b of the frame is bit (b % 8) of byte (b / 8), bit 0
// the least significant.
//   Intel (@1, little-endian): start bit = the signal's least significant bit;
//     higher bits follow at start+1, start+2, ... across bytes upwards.
//   Motorola (@0, big-endian): start bit = the signal's most significant bit;
//     lower bits follow towards bit 0 of that byte, then continue at bit 7 of
//     the NEXT byte (byte index + 1).
// Both are done by viewing the 8 bytes as one 64-bit word: little-endian for
// Intel, big-endian for Motorola, so a signal is one shift and mask.
#pragma once

#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <span>

namespace markloop::dbc {

inline constexpr std::size_t kMaxPayload = 8;  // classic CAN

enum class ByteOrder : std::uint8_t { Intel, Motorola };

struct SignalLayout {
  std::uint8_t start_bit;  // as written in the DBC
  std::uint8_t length;     // bits, 1..32
  ByteOrder order;
  bool is_signed;
};

namespace detail {

constexpr std::uint64_t low_mask(unsigned length) noexcept {
  return length >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << length) - 1;
}

// Bit position of the signal's least significant bit in the word that
// load_little()/load_big() builds.
constexpr unsigned word_shift(const SignalLayout& s) noexcept {
  if (s.order == ByteOrder::Intel) return s.start_bit;
  // Motorola: in the big-endian word, byte i occupies bits 63-8i .. 56-8i and
  // DBC bit (8i + j) sits at word bit 56 - 8i + j.
  const unsigned msb_in_word = 56U - 8U * (s.start_bit / 8U) + (s.start_bit % 8U);
  return msb_in_word + 1U - s.length;
}

constexpr std::uint64_t load(std::span<const std::uint8_t> data, ByteOrder order) noexcept {
  std::uint64_t word = 0;
  for (std::size_t i = 0; i < data.size() && i < kMaxPayload; ++i) {
    const unsigned shift =
        order == ByteOrder::Intel ? static_cast<unsigned>(8 * i) : static_cast<unsigned>(56 - 8 * i);
    word |= std::uint64_t{data[i]} << shift;
  }
  return word;
}

constexpr void store(std::span<std::uint8_t> data, ByteOrder order, std::uint64_t word,
                     std::uint64_t touched) noexcept {
  for (std::size_t i = 0; i < data.size() && i < kMaxPayload; ++i) {
    const unsigned shift =
        order == ByteOrder::Intel ? static_cast<unsigned>(8 * i) : static_cast<unsigned>(56 - 8 * i);
    const auto keep = static_cast<std::uint8_t>(~(touched >> shift) & 0xFFU);
    const auto put = static_cast<std::uint8_t>((word >> shift) & 0xFFU);
    data[i] = static_cast<std::uint8_t>((data[i] & keep) | put);
  }
}

}  // namespace detail

// True when the signal lies entirely inside a payload of `length` bytes (used
// in static_asserts on the generated layouts).
constexpr bool fits_in(const SignalLayout& s, std::size_t length) noexcept {
  if (s.length == 0 || s.length > 32 || length > kMaxPayload) return false;
  if (s.order == ByteOrder::Intel) return s.start_bit + s.length <= 8 * length;
  const unsigned msb_in_word = 56U - 8U * (s.start_bit / 8U) + (s.start_bit % 8U);
  if (msb_in_word + 1U < s.length) return false;  // runs past byte 7
  const unsigned lsb_in_word = msb_in_word + 1U - s.length;
  return lsb_in_word >= 64U - 8U * length;  // last byte touched < length
}

// The frame bits a signal covers, as a mask in DBC bit numbering (bit b of the
// mask is bit b % 8 of byte b / 8).
constexpr std::uint64_t occupied_bits(const SignalLayout& s) noexcept {
  const std::uint64_t in_word = detail::low_mask(s.length) << detail::word_shift(s);
  if (s.order == ByteOrder::Intel) return in_word;
  std::uint64_t swapped = 0;  // big-endian word -> DBC numbering is a byte swap
  for (unsigned i = 0; i < 8; ++i) swapped |= ((in_word >> (56U - 8U * i)) & 0xFFU) << (8U * i);
  return swapped;
}

// True when no two of the signals share a bit.
constexpr bool disjoint(std::initializer_list<SignalLayout> signals) noexcept {
  std::uint64_t used = 0;
  for (const SignalLayout& s : signals) {
    if ((used & occupied_bits(s)) != 0) return false;
    used |= occupied_bits(s);
  }
  return true;
}

// The raw (unscaled) bits of a signal; the caller checks the payload length.
constexpr std::uint64_t extract_raw(std::span<const std::uint8_t> data, const SignalLayout& s) noexcept {
  return (detail::load(data, s.order) >> detail::word_shift(s)) & detail::low_mask(s.length);
}

// The raw value as a number: sign-extended for signed signals.
constexpr std::int64_t extract(std::span<const std::uint8_t> data, const SignalLayout& s) noexcept {
  const std::uint64_t raw = extract_raw(data, s);
  if (s.is_signed && ((raw >> (s.length - 1U)) & 1U) != 0) {
    return static_cast<std::int64_t>(raw | ~detail::low_mask(s.length));
  }
  return static_cast<std::int64_t>(raw);
}

// Writes the low `length` bits of `raw` (two's complement for negatives) and
// leaves every other bit of the payload as it was.
constexpr void insert(std::span<std::uint8_t> data, const SignalLayout& s, std::int64_t raw) noexcept {
  const unsigned shift = detail::word_shift(s);
  const std::uint64_t mask = detail::low_mask(s.length);
  const std::uint64_t bits = static_cast<std::uint64_t>(raw) & mask;
  detail::store(data, s.order, bits << shift, mask << shift);
}

}  // namespace markloop::dbc
