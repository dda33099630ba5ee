// foamd's HTTP side for dashboards and scrapers: the dashboard page at `/`, read-only JSON of
// jobs, samples and results, CSV and VTK downloads, snapshots as binary meshes for the 3D view
// (mesh_frame.h), /metrics and /healthz. Requests are parsed and answered by cpp-httplib on a
// pool of worker threads; connections are accepted and their headers read by HttpFront
// (http_front.h), which hands a worker only whole requests. With the gRPC listener's rules: a
// token guards every data route, and a non-loopback address needs a token and TLS.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include "executor.h"
#include "store.h"

typedef struct ssl_ctx_st SSL_CTX;

namespace httplib {
class Server;
}

namespace activefoam::server {

class HttpFront;

struct HttpOptions {
  std::string listen;         // HOST:PORT (port 0: any free one)
  std::string token;          // empty: no authentication
  std::string tls_cert_path;  // PEM files, both or neither
  std::string tls_key_path;
  bool metrics_public = false;  // /metrics without the token (for Prometheus scrapers)
  // Workers answer whole requests only (the front reads the headers): idle and slow clients
  // never hold one. /healthz has a worker of its own besides.
  int threads = 32;
  int header_timeout_s = 5;  // the whole request header (and a TLS handshake), from the accept
  int read_timeout_s = 5;    // each later read and each write of the answer
  int max_connections_per_client = 64;  // one more closes the client's oldest unfinished one
  int max_connections = 512;            // all clients together
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
  std::unique_ptr<httplib::Server> http_;  // routes and answers (no sockets of its own)
  SSL_CTX* tls_ = nullptr;
  int port_ = 0;
  std::unique_ptr<HttpFront> front_;
};

}  // namespace activefoam::server
