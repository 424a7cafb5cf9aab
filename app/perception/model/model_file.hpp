// The marking classifier's model files (README.md beside this file): a
// 64-byte header (magic, format version, kind, members, shapes, value
// count, CRC-32 of the payload), then the float32 values, little-endian.
// markloop-train writes them; the tests read them. The build reads them
// with model_file.py, which keeps the same layout.
#pragma once

#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <string_view>

#include "app/common/crc32.hpp"
#include "app/common/result.hpp"

namespace markloop::perception::model_file {

static_assert(std::endian::native == std::endian::little, "model files hold little-endian floats");

inline constexpr std::array<char, 4> kMagic = {'M', 'L', 'W', 'T'};
inline constexpr std::uint32_t kVersion = 1;

enum class Kind : std::uint32_t { kMlp = 1, kCnn = 2 };

inline constexpr int kShapeWords = 10;

// Shapes: MLP {inputs, hidden, outputs}; CNN {input channels, patch rows,
// patch cols, shape features, channels 1..3, hidden, outputs}; the rest 0.
struct Header {
  std::array<char, 4> magic;
  std::uint32_t version;
  Kind kind;
  std::uint32_t members;
  std::array<std::uint32_t, kShapeWords> shape;
  std::uint32_t elements;  // float32 values in the payload
  std::uint32_t crc32;     // of the payload's bytes (zlib's CRC-32)
};
static_assert(sizeof(Header) == 64 && offsetof(Header, shape) == 16 && offsetof(Header, elements) == 56 &&
                  offsetof(Header, crc32) == 60,
              "the model file's header layout");

inline std::uint32_t payload_crc(std::span<const float> values) {
  return ecu::crc32({reinterpret_cast<const std::uint8_t*>(values.data()), values.size_bytes()});
}

// The file's bytes.
inline std::string encode(Kind kind, std::uint32_t members,
                          const std::array<std::uint32_t, kShapeWords>& shape,
                          std::span<const float> values) {
  const Header header{
      kMagic, kVersion, kind, members, shape, static_cast<std::uint32_t>(values.size()), payload_crc(values)};
  std::string bytes(sizeof header + values.size_bytes(), '\0');
  std::memcpy(bytes.data(), &header, sizeof header);
  std::memcpy(bytes.data() + sizeof header, values.data(), values.size_bytes());
  return bytes;
}

// A file's header and payload, checked: the magic, version, size and CRC
// (the shapes are the caller's to judge). The payload points into `bytes`.
struct Decoded {
  Header header;
  std::span<const std::byte> payload;
};

inline Result<Decoded> decode(std::string_view bytes, const std::string& where) {
  Decoded d{};
  if (bytes.size() < sizeof(Header))
    return error(where + ": " + std::to_string(bytes.size()) + " bytes, shorter than the 64-byte header");
  std::memcpy(&d.header, bytes.data(), sizeof(Header));
  if (d.header.magic != kMagic) return error(where + ": not a markloop model file");
  if (d.header.version != kVersion)
    return error(where + ": format version " + std::to_string(d.header.version) + ", expected " +
                 std::to_string(kVersion));
  const std::size_t expected = sizeof(Header) + std::size_t{4} * d.header.elements;
  if (bytes.size() != expected)
    return error(where + ": " + std::to_string(bytes.size()) + " bytes, the header gives " +
                 std::to_string(expected));
  d.payload = std::as_bytes(std::span(bytes).subspan(sizeof(Header)));
  if (ecu::crc32({reinterpret_cast<const std::uint8_t*>(d.payload.data()), d.payload.size()}) !=
      d.header.crc32)
    return error(where + ": the payload's CRC-32 does not match the header's: the file is damaged");
  return d;
}

}  // namespace markloop::perception::model_file
