// Listener rules shared by foamd's gRPC and HTTP sides.
#pragma once

#include <string>

namespace activefoam::server {

// HOST:PORT names this machine's loopback interface (127.0.0.0/8, ::1, localhost).
inline bool isLoopback(const std::string& hostport) {
  const std::string host = hostport.substr(0, hostport.rfind(':'));
  return host == "localhost" || host == "[::1]" || host == "::1" || host.rfind("127.", 0) == 0;
}

}  // namespace activefoam::server
