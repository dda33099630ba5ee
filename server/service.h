// foamd's gRPC side: the activefoam.v1.Foam service, health, reflection, auth and TLS.
// The only server translation unit (with server.cc's main) that includes gRPC headers.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "executor.h"
#include "store.h"

namespace activefoam::server {

struct ServerConfig {
  std::string listen = "127.0.0.1:50051";
  std::string token;     // empty: no authentication
  std::string tls_cert;  // PEM file contents (both or neither)
  std::string tls_key;
  // A non-loopback listen address without a token is refused unless this is set.
  bool insecure_public = false;
  // The transport's limit on a request; well above the 256 KiB a spec may have
  // (kMaxSpecTextBytes), so that an oversized spec gets an answer naming the field and the
  // limit rather than gRPC's own refusal.
  int max_message_bytes = 16 * 1024 * 1024;
  // Accept specs beyond the measured stable range (--allow-unstable; ConvertOptions).
  bool allow_unstable = false;
};

// Throws std::invalid_argument when the listener breaks a rule: a non-loopback address needs a
// token (or insecure_public), and a token there needs TLS. The message names the flags.
void checkServerConfig(const ServerConfig& config);

class FoamServer {
 public:
  FoamServer(Store& store, Executor& pool, ServerConfig config);
  ~FoamServer();
  // Binds and starts serving; throws std::runtime_error when it cannot bind.
  void start();
  int port() const;  // the bound port (useful with listen = "127.0.0.1:0")
  void shutdown();   // stops accepting, ends open streams
  void wait();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace activefoam::server
