// HOST:PORT addresses as foam and foamd take them: the port must be a number in 1..65535
// (gRPC and the HTTP library take the port modulo 65536 otherwise: --listen 127.0.0.1:92786
// listened on 27250).
#pragma once

#include <string>

namespace activefoam {

// "" when `hostport` is HOST:PORT (HOST a name, an IPv4 address or [IPv6]) with PORT in
// 1..65535 (0..65535 for a listener: port 0 lets the system choose one); otherwise what is
// wrong, for an error naming the option.
inline std::string hostPortError(const std::string& hostport, bool listener = false) {
  const std::size_t colon = hostport.rfind(':');
  if (colon == std::string::npos || colon == 0) return "'" + hostport + "' is not HOST:PORT";
  const std::string host = hostport.substr(0, colon), port = hostport.substr(colon + 1);
  if (host.front() != '[' && host.find(':') != std::string::npos)
    return "'" + hostport + "': an IPv6 host needs brackets, e.g. [::1]:50051";
  if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos)
    return "'" + hostport + "': the port '" + port + "' is not a number in " +
           (listener ? "0" : "1") + "..65535";
  const long p = std::stol(port);
  if (p < (listener ? 0 : 1) || p > 65535)
    return "'" + hostport + "': the port " + port + " is outside " + (listener ? "0" : "1") +
           "..65535";
  return "";
}

}  // namespace activefoam
