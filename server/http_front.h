// The accept side of foamd's HTTP endpoint. cpp-httplib's own loop gives each
// accepted connection a pool worker at once and reads its header there with a timeout per read:
// idle sockets and clients sending a header line every few seconds occupied every worker, and
// /healthz waited behind them (33 slow clients held it for 43 s, 200 idle sockets for 19 s).
//
// HttpFront reads every request header itself, on one epoll thread, with non-blocking sockets
// (and the TLS handshake, non-blocking too), and hands a worker only a connection whose header
// is complete; the library then parses and answers it from what was read. So:
//   - the whole header (and a TLS handshake) must arrive within `header_timeout_s` of the
//     accept, however it trickles in (408, then the connection is closed);
//   - each client address holds at most `max_per_client` connections: one more closes that
//     address's oldest connection still sending its header (or, when it has none, is refused
//     with 503), and all clients together at most `max_connections`;
//   - `GET /healthz` and `HEAD /healthz` have their own worker: slow answers to other routes
//     cannot delay a liveness probe either.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <unordered_map>

typedef struct ssl_ctx_st SSL_CTX;

namespace httplib {
class Stream;
}

namespace activefoam::server {

struct FrontOptions {
  int workers = 32;           // answer whole requests (the health worker is one more)
  int header_timeout_s = 5;   // accept → the end of the header, TLS handshake included
  int io_timeout_s = 5;       // each later read (a body) and each write of the answer
  int max_per_client = 64;    // connections held per client address
  int max_connections = 512;  // by all clients together
};

// Binds a listening TCP socket on HOST:PORT (port 0: a free one) with SO_REUSEADDR only (no
// SO_REUSEPORT: a second server on the port must fail). Returns the socket and sets `port`, or
// returns -1.
int bindHttpListener(const std::string& host, int& port);

class HttpFront {
 public:
  // Serves one whole request from the stream and returns; the front closes the connection.
  using Serve = std::function<void(httplib::Stream&)>;
  // Takes `listen_fd`; `tls` (may be null) is used, not owned: it must outlive the front.
  HttpFront(int listen_fd, SSL_CTX* tls, FrontOptions options, Serve serve);
  ~HttpFront();
  HttpFront(const HttpFront&) = delete;
  HttpFront& operator=(const HttpFront&) = delete;

 private:
  struct Conn;
  struct Lane;
  void loop();
  void acceptSome();
  void onReady(Conn* c);
  void handOff(Conn* c);
  void drop(Conn* c, const char* answer);
  bool evictOldest(const std::string* addr);
  void release(const std::string& addr);
  int held(const std::string& addr);
  int total();

  int listen_fd_;
  SSL_CTX* tls_;
  FrontOptions options_;
  Serve serve_;
  int epoll_fd_ = -1;
  int wake_fd_ = -1;
  int reserve_fd_ = -1;  // closed to accept-and-close when out of file descriptors
  std::atomic<bool> stopping_{false};
  std::unique_ptr<Lane> general_, health_;
  std::mutex count_mu_;  // the counts below (workers release their connections)
  std::unordered_map<std::string, int> per_client_;
  int total_ = 0;
  struct Waiting;
  std::unique_ptr<Waiting> waiting_;  // the epoll thread's own
  std::thread thread_;
};

}  // namespace activefoam::server
