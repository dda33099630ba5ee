// Listener rules shared by foamd's gRPC and HTTP sides.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <string>

namespace activefoam::server {

// HOST:PORT names this machine's loopback interface (127.0.0.0/8, ::1, localhost).
inline bool isLoopback(const std::string& hostport) {
  const std::string host = hostport.substr(0, hostport.rfind(':'));
  return host == "localhost" || host == "[::1]" || host == "::1" || host.rfind("127.", 0) == 0;
}

// Empty, or why listening on `hostport` (HOST:PORT, checked by hostPortError) would be
// ambiguous: the same port on the other loopback family (127.0.0.1 for ::1 and the reverse)
// is taken, and `localhost:PORT` — which clients resolve to either — would then reach one
// server or the other (a foamd on [::1]:P started beside one on 127.0.0.1:P, and
// `foam --server localhost:P` found none of the first's jobs). Port 0 (the system's choice)
// is never ambiguous.
inline std::string loopbackSiblingTaken(const std::string& hostport) {
  const std::size_t colon = hostport.rfind(':');
  if (colon == std::string::npos) return "";
  const std::string host = hostport.substr(0, colon), digits = hostport.substr(colon + 1);
  if (digits.empty() || digits.size() > 5 ||
      digits.find_first_not_of("0123456789") != std::string::npos)
    return "";
  const int port = std::stoi(digits);
  if (port <= 0) return "";
  const bool v6 = host == "::1" || host == "[::1]";
  const bool v4 = host.rfind("127.", 0) == 0 || host == "localhost";
  if (!v4 && !v6) return "";
  const int fd = ::socket(v6 ? AF_INET : AF_INET6, SOCK_STREAM, 0);
  if (fd < 0) return "";  // no such family here: nothing to collide with
  int yes = 1;
  if (!v6) ::setsockopt(fd, IPPROTO_IPV6, IPV6_V6ONLY, &yes, sizeof yes);
  ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);  // TIME_WAIT is no server
  int rc;
  if (v6) {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    rc = ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  } else {
    sockaddr_in6 a{};
    a.sin6_family = AF_INET6;
    a.sin6_port = htons(static_cast<std::uint16_t>(port));
    a.sin6_addr = in6addr_loopback;
    rc = ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  }
  const int err = errno;
  ::close(fd);
  if (rc == 0 || err != EADDRINUSE) return "";
  return std::string("port ") + std::to_string(port) + " is taken on " +
         (v6 ? "127.0.0.1" : "[::1]") + " (another foamd?): `localhost:" + std::to_string(port) +
         "` would reach either server; give this one another port";
}

}  // namespace activefoam::server
