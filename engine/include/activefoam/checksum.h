// A 64-bit checksum of a byte string (FNV-1a), and the trailer that seals a byte string with it:
// checkpoints carry one, so that a damaged one is refused before anything is read from it.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace activefoam {

inline std::uint64_t checksum64(std::string_view bytes) {
  std::uint64_t h = 1469598103934665603ULL;
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 1099511628211ULL;
  }
  return h;
}

// `bytes` followed by its checksum, 8 bytes little-endian.
inline std::string sealed(std::string bytes) {
  std::uint64_t h = checksum64(bytes);
  for (int i = 0; i < 8; ++i, h >>= 8) bytes.push_back(static_cast<char>(h & 0xFF));
  return bytes;
}

// What `sealed` wrapped, when its trailer matches; nullopt when the bytes are damaged (any bit
// of content or trailer changed, or cut).
inline std::optional<std::string_view> unsealed(std::string_view bytes) {
  if (bytes.size() < 8) return std::nullopt;
  const std::string_view body = bytes.substr(0, bytes.size() - 8);
  std::uint64_t stored = 0;
  for (int i = 7; i >= 0; --i)
    stored = (stored << 8) | static_cast<unsigned char>(bytes[body.size() + i]);
  if (stored != checksum64(body)) return std::nullopt;
  return body;
}

}  // namespace activefoam
