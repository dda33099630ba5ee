// TLS certificate and key files, read so that a wrong file is named as such (a garbage
// --tls-ca surfaced as gRPC's "empty address list: (14)", a key that is not the certificate's as
// "the port is taken"). A private key is refused when other users could read it, as token files.
#pragma once

#include <sys/stat.h>

#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

namespace activefoam {

enum class PemKind { Certificate, PrivateKey };

// The file's text. Throws std::runtime_error naming `option` and the file: not a regular file,
// over 1 MiB, no PEM block of the kind asked for, or (a private key) readable by others.
inline std::string readPemFile(const std::string& path, const std::string& option, PemKind kind) {
  const std::string what = option + " '" + path + "'";
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode))
    throw std::runtime_error(what + ": not a readable file");
  if (st.st_size > (1 << 20))
    throw std::runtime_error(what + " holds " + std::to_string(st.st_size) +
                             " bytes; a PEM file here has at most 1 MiB");
  if (kind == PemKind::PrivateKey && (st.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    throw std::runtime_error(what + ": a private key accessible to other users (mode " + mode +
                             "): chmod 600 '" + path + "'");
  }
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  if (!in) throw std::runtime_error(what + ": cannot read it");
  const std::string text = s.str();
  if (kind == PemKind::Certificate) {
    if (text.find("-----BEGIN CERTIFICATE-----") == std::string::npos)
      throw std::runtime_error(what +
                               ": not a PEM certificate (no '-----BEGIN CERTIFICATE-----' "
                               "line)");
  } else {
    const std::size_t begin = text.find("-----BEGIN ");
    const std::size_t end = begin == std::string::npos ? begin : text.find('\n', begin);
    if (begin == std::string::npos ||
        text.substr(begin, end - begin).find("PRIVATE KEY-----") == std::string::npos)
      throw std::runtime_error(what +
                               ": not a PEM private key (no '-----BEGIN ... PRIVATE "
                               "KEY-----' line)");
    if (text.find("ENCRYPTED") != std::string::npos)
      throw std::runtime_error(what +
                               ": an encrypted private key; foamd needs it unencrypted "
                               "(openssl pkey -in KEY -out KEY.plain)");
  }
  return text;
}

}  // namespace activefoam
