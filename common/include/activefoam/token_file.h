// Bearer-token files, read the way ssh reads private keys: refused when other users could read
// them or when they are too short to be a secret.
#pragma once

#include <sys/stat.h>

#include <cctype>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

namespace activefoam {

inline constexpr std::size_t kMinTokenBytes = 16;
inline constexpr std::size_t kMaxTokenBytes = 4096;

// "" when `token` can be a bearer token: kMinTokenBytes..kMaxTokenBytes of printable ASCII
// without spaces (what an HTTP header and gRPC metadata carry as they are). Otherwise what is
// wrong (a token with a newline inside or binary bytes aborted foam in gRPC's
// metadata check, and a 1 MB one broke every client).
inline std::string tokenError(const std::string& token) {
  if (token.size() < kMinTokenBytes)
    return "holds " + std::to_string(token.size()) + " bytes; a token needs at least " +
           std::to_string(kMinTokenBytes);
  if (token.size() > kMaxTokenBytes)
    return "holds " + std::to_string(token.size()) + " bytes; a token has at most " +
           std::to_string(kMaxTokenBytes);
  for (std::size_t i = 0; i < token.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(token[i]);
    if (c < 0x21 || c > 0x7e) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "0x%02x", c);
      return std::string("has byte ") + hex + " at offset " + std::to_string(i) +
             ": a token is printable ASCII without spaces";
    }
  }
  return "";
}

// The token (surrounding whitespace removed). Throws std::runtime_error naming the file and
// what to do.
inline std::string readTokenFile(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode))
    throw std::runtime_error("token file '" + path + "': not a readable file");
  if ((st.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    throw std::runtime_error("token file '" + path + "' is accessible to other users (mode " +
                             mode + "): chmod 600 '" + path + "'");
  }
  if (st.st_size > static_cast<off_t>(4 * kMaxTokenBytes))
    throw std::runtime_error("token file '" + path + "' holds " + std::to_string(st.st_size) +
                             " bytes; a token has at most " + std::to_string(kMaxTokenBytes));
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  if (!in) throw std::runtime_error("token file '" + path + "': cannot read it");
  std::string token = s.str();
  while (!token.empty() && std::isspace(static_cast<unsigned char>(token.back()))) token.pop_back();
  std::size_t i = 0;
  while (i < token.size() && std::isspace(static_cast<unsigned char>(token[i]))) ++i;
  token.erase(0, i);
  if (const std::string bad = tokenError(token); !bad.empty())
    throw std::runtime_error("token file '" + path + "' " + bad +
                             " (e.g. head -c 24 /dev/urandom | base64 > '" + path + "')");
  return token;
}

}  // namespace activefoam
