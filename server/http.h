// foamd's HTTP side for dashboards and scrapers: the dashboard page at `/`, read-only JSON of
// jobs, samples and results, CSV and VTK downloads, snapshots as binary meshes for the 3D view
// (mesh_frame.h), /metrics and /healthz. Served by
// cpp-httplib (a pool of worker threads, read and keep-alive timeouts), with the gRPC
// listener's rules: a token guards every data route, and a non-loopback address needs a token
// and TLS.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <thread>

#include "executor.h"
#include "store.h"

namespace httplib {
class Server;
}

namespace activefoam::server {

struct HttpOptions {
  std::string listen;         // HOST:PORT (port 0: any free one)
  std::string token;          // empty: no authentication
  std::string tls_cert_path;  // PEM files, both or neither
  std::string tls_key_path;
  bool metrics_public = false;  // /metrics without the token (for Prometheus scrapers)
  // Each open connection holds a worker while it is kept alive or being read: the pool must
  // outnumber the idle and slow clients that a dashboard host sees, and the timeouts end them.
  int threads = 32;
  int read_timeout_s = 5;
  int keep_alive_timeout_s = 5;
  std::size_t max_target_bytes = 8192;  // longer request targets get 414
};

// Throws std::invalid_argument when the options break a listener rule (a non-loopback address
// without a token and TLS, half a TLS pair, a pool out of range); the message names the flags.
void checkHttpOptions(const HttpOptions& options);

inline HttpOptions loopbackOptions(const std::string& listen) {
  HttpOptions o;
  o.listen = listen;
  return o;
}

class HttpEndpoint {
 public:
  HttpEndpoint(Store& store, Executor& pool, HttpOptions options);  // throws when it cannot bind
  // Loopback, no token: what tests and a local dashboard use.
  HttpEndpoint(Store& store, Executor& pool, const std::string& listen)
      : HttpEndpoint(store, pool, loopbackOptions(listen)) {}
  ~HttpEndpoint();
  int port() const { return port_; }

  // The response body and content type for a request target (path and query), without the
  // transport or the token check (exposed for tests); status in `code`.
  std::string handle(const std::string& target, int& code, std::string& content_type);

 private:
  Store& store_;
  Executor& pool_;
  HttpOptions options_;
  std::unique_ptr<httplib::Server> http_;
  int port_ = 0;
  std::thread thread_;
};

}  // namespace activefoam::server
