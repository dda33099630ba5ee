// foamd's HTTP endpoint as a client meets it over the socket: a pool of workers that idle and
// slow clients cannot hold, limits with their status codes, the token on every data route, TLS,
// and the listener rules shared with gRPC.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <random>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "http.h"
#include "pool.h"
#include "process.h"
#include "service.h"
#include "store.h"

// Last: it pulls in <resolv.h>, whose `_res` macro breaks Eigen parameter names.
#include <httplib.h>

using namespace activefoam::server;
using namespace std::chrono_literals;
namespace fs = std::filesystem;
using activefoam::testing::sh;
using activefoam::testing::tempDir;

namespace {

int connectTo(int port) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  EXPECT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  return fd;
}

class HttpTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = tempDir();
    store_ = std::make_unique<Store>((dir_ / "f.db").string());
    pool_ = std::make_unique<Pool>(*store_, PoolOptions{});  // never started: no jobs run
  }
  void TearDown() override {
    http_.reset();
    pool_.reset();
    store_.reset();
    fs::remove_all(dir_);
  }
  HttpEndpoint& start(HttpOptions o) {
    if (o.listen.empty()) o.listen = "127.0.0.1:0";
    http_ = std::make_unique<HttpEndpoint>(*store_, *pool_, o);
    return *http_;
  }
  httplib::Client client(const std::string& token = "") {
    httplib::Client c("127.0.0.1", http_->port());
    c.set_connection_timeout(2, 0);
    c.set_read_timeout(5, 0);
    if (!token.empty()) c.set_bearer_token_auth(token.c_str());
    return c;
  }

  fs::path dir_;
  std::unique_ptr<Store> store_;
  std::unique_ptr<Pool> pool_;
  std::unique_ptr<HttpEndpoint> http_;
};

}  // namespace

// The hand-written server this replaced served one connection at a time: one client sending a
// byte every 1.5 s held /healthz for 11.5 s.
TEST_F(HttpTest, IdleConnectionsAndASlowClientDoNotDelayHealthz) {
  HttpEndpoint& http = start({});
  std::vector<int> idle;
  for (int k = 0; k < 20; ++k) idle.push_back(connectTo(http.port()));
  std::atomic<bool> stop{false};
  std::thread drip([&] {
    const int fd = connectTo(http.port());
    const std::string req = "GET /jobs HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Padding: ";
    for (std::size_t k = 0; !stop; k = (k + 1) % req.size()) {
      (void)send(fd, req.data() + k, 1, MSG_NOSIGNAL);
      for (int i = 0; i < 15 && !stop; ++i) std::this_thread::sleep_for(100ms);
    }
    close(fd);
  });
  std::this_thread::sleep_for(300ms);  // every connection accepted and waiting
  for (int k = 0; k < 5; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    auto res = client().Get("/healthz");
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ASSERT_TRUE(res) << httplib::to_string(res.error());
    EXPECT_EQ(res->status, 200);
    EXPECT_LT(s, 1.0) << "try " << k;
    std::this_thread::sleep_for(200ms);
  }
  stop = true;
  drip.join();
  for (int fd : idle) close(fd);
}

// The library's pool gave each connection a worker while its header was read,
// with a timeout per read: 33 clients sending a header line every 3 s held /healthz for 43 s, 200
// idle sockets for 19 s. Now the front reads every header itself and hands a worker only whole
// requests. The flood reconnects whatever the server closes, so it stays 200 idle and 50 slow
// connections for the whole test (all from 127.0.0.1, the address /healthz is asked from).
TEST_F(HttpTest, HealthzAnswersWithinASecondUnder200IdleAnd50SlowConnections) {
  HttpEndpoint& http = start({});
  const int port = http.port();
  std::atomic<bool> stop{false};
  std::atomic<int> reconnects{0};
  std::thread flood([&] {
    auto open = [&] {
      const int fd = socket(AF_INET, SOCK_STREAM, 0);
      sockaddr_in a{};
      a.sin_family = AF_INET;
      a.sin_port = htons(static_cast<std::uint16_t>(port));
      a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
      (void)connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
      return fd;
    };
    auto closed = [](int fd) {
      char c;
      const ssize_t n = recv(fd, &c, 1, MSG_DONTWAIT | MSG_PEEK);
      return n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK);
    };
    const std::string first = "GET /jobs HTTP/1.1\r\nHost: 127.0.0.1\r\n";
    std::vector<int> idle(200), slow(50);
    for (int& fd : idle) fd = open();
    for (int& fd : slow) {
      fd = open();
      (void)send(fd, first.data(), first.size(), MSG_NOSIGNAL);
    }
    for (int tick = 1; !stop; ++tick) {
      std::this_thread::sleep_for(250ms);
      for (int& fd : idle)
        if (closed(fd)) {
          close(fd);
          fd = open();
          ++reconnects;
        }
      const bool line_due = tick % 8 == 0;  // a header line every 2 s
      for (int& fd : slow) {
        const std::string line = "X-Slow-" + std::to_string(tick) + ": 1\r\n";
        if (closed(fd) || (line_due && send(fd, line.data(), line.size(), MSG_NOSIGNAL) !=
                                           static_cast<ssize_t>(line.size()))) {
          close(fd);
          fd = open();
          (void)send(fd, first.data(), first.size(), MSG_NOSIGNAL);
          ++reconnects;
        }
      }
    }
    for (int fd : idle) close(fd);
    for (int fd : slow) close(fd);
  });
  struct Join {  // also when an assertion returns early
    std::atomic<bool>& stop;
    std::thread& t;
    ~Join() {
      stop = true;
      t.join();
    }
  } join{stop, flood};
  std::this_thread::sleep_for(500ms);  // the flood connected
  // 8 tries over ~9 s: past the 5 s header deadline, while the flood's closed connections
  // come back.
  for (int k = 0; k < 8; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    auto res = client().Get("/healthz");
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ASSERT_TRUE(res) << "try " << k << ": " << httplib::to_string(res.error()) << " after " << s
                     << " s";
    EXPECT_EQ(res->status, 200);
    EXPECT_LT(s, 1.0) << "try " << k;
    std::this_thread::sleep_for(1s);
  }
  std::printf("the flood reconnected %d times\n", reconnects.load());
}

// The front's two limits. A header must be whole within its deadline however
// it trickles in: a line every 300 ms never let the library's per-read timeout fire. And one
// address holds at most its share of connections: one more closes its oldest unfinished one.
TEST_F(HttpTest, AHeaderHasADeadlineAndAnAddressHoldsItsShareOfConnections) {
  HttpOptions o;
  o.header_timeout_s = 1;
  o.max_connections_per_client = 8;
  HttpEndpoint& http = start(o);
  const int slow = connectTo(http.port());
  const auto t0 = std::chrono::steady_clock::now();
  const std::string first = "GET /jobs HTTP/1.1\r\nHost: 127.0.0.1\r\n";
  (void)send(slow, first.data(), first.size(), MSG_NOSIGNAL);
  std::string got;
  double closed_after = -1;
  for (int k = 0; k < 20 && closed_after < 0; ++k) {  // 6 s at most
    pollfd p{slow, POLLIN, 0};
    if (poll(&p, 1, 300) == 0) {
      const std::string line = "X-Line-" + std::to_string(k) + ": 1\r\n";
      (void)send(slow, line.data(), line.size(), MSG_NOSIGNAL);
      continue;
    }
    char buf[512];
    const ssize_t n = recv(slow, buf, sizeof buf, 0);
    if (n > 0) got.append(buf, static_cast<std::size_t>(n));
    if (n <= 0)
      closed_after = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  close(slow);
  EXPECT_EQ(got.rfind("HTTP/1.1 408", 0), 0u) << got;
  EXPECT_GT(closed_after, 0.9);
  EXPECT_LT(closed_after, 2.5);

  std::vector<int> idle;
  for (int k = 0; k < 12; ++k) idle.push_back(connectTo(http.port()));
  std::this_thread::sleep_for(300ms);
  for (int k = 0; k < 12; ++k) {
    char c;
    const ssize_t n = recv(idle[k], &c, 1, MSG_DONTWAIT | MSG_PEEK);
    const bool closed = n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK);
    EXPECT_EQ(closed, k < 4) << "connection " << k;
  }
  auto res = client().Get("/healthz");  // a whole request from the same address still passes
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  for (int fd : idle) close(fd);
}

TEST_F(HttpTest, LimitsAnswerWithTheirStatus) {
  start({});
  auto c = client();
  auto res = c.Get("/jobs?tag=" + std::string(20 * 1024, 'a'));
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 414);
  EXPECT_NE(res->body.find("too long"), std::string::npos) << res->body;
  // A truncated filter must never answer 200: just under the limit still filters correctly.
  res = c.Get("/jobs?tag=" + std::string(8000, 'a'));
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_NE(res->body.find("\"jobs\":[]"), std::string::npos) << res->body;
  res = c.Post("/jobs", std::string(100 * 1024, 'x'), "text/plain");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 405);  // the method decides, before any body is read
  res = c.Delete("/jobs/j-1");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 405);
  EXPECT_EQ(res->get_header_value("Allow"), "GET, HEAD");
}

// What a raw client gets for `request` and how long until the server closed the connection.
struct RawAnswer {
  std::string text;
  double seconds = 0;
  int responses = 0;
};
RawAnswer rawExchange(int port, const std::string& request) {
  const int fd = connectTo(port);
  timeval tv{10, 0};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  const auto t0 = std::chrono::steady_clock::now();
  for (std::size_t sent = 0; sent < request.size();) {
    const ssize_t n = ::send(fd, request.data() + sent, request.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) break;  // the server may close before reading what it refuses
    sent += static_cast<std::size_t>(n);
  }
  RawAnswer a;
  char buf[4096];
  for (ssize_t n; (n = ::recv(fd, buf, sizeof buf, 0)) > 0;) a.text.append(buf, n);
  a.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  close(fd);
  for (std::size_t at = 0; (at = a.text.find("HTTP/1.1 ", at)) != std::string::npos; ++at)
    ++a.responses;
  return a;
}

// A GET with a body (100 KiB, or a chunked 1 MiB) was answered 200 and its
// unread body parsed as a second request; a POST without Content-Length got 400 after 10 s; every
// refusal held the connection for the 5 s keep-alive. Now: 413 / 405 / 414 at once, the
// connection closed after the one answer.
TEST_F(HttpTest, RefusalsAnswerAtOnceAndCloseTheConnection) {
  start({});
  const int port = http_->port();
  const std::string host = "Host: 127.0.0.1\r\n";
  struct Case {
    std::string request, status;
  };
  const std::vector<Case> cases = {
      {"GET /healthz HTTP/1.1\r\n" + host + "Content-Length: 102400\r\n\r\n" +
           std::string(102400, 'x'),
       "413"},
      {"GET /healthz HTTP/1.1\r\n" + host + "Transfer-Encoding: chunked\r\n\r\n100000\r\n" +
           std::string(1 << 20, 'x') + "\r\n0\r\n\r\n",
       "413"},
      {"POST /jobs HTTP/1.1\r\n" + host + "\r\n", "405"},
      {"GET /" + std::string(9000, 'a') + " HTTP/1.1\r\n" + host + "\r\n", "414"},
      {"GET /healthz HTTP/1.1\r\n" + host + "\r\n", "200"}};
  for (const Case& c : cases) {
    const RawAnswer a = rawExchange(port, c.request);
    EXPECT_EQ(a.text.substr(0, 12), "HTTP/1.1 " + c.status) << a.text.substr(0, 200);
    EXPECT_EQ(a.responses, 1) << a.text.substr(0, 400);
    EXPECT_LT(a.seconds, 1.0) << c.request.substr(0, 40);
  }
}

// Without a token the dashboard answered any Host, so a page elsewhere that rebinds
// its DNS name to 127.0.0.1 could read every job. Only loopback names are served then; with a
// token the token decides.
TEST_F(HttpTest, WithoutATokenOnlyLoopbackHostNamesAreServed) {
  start({});
  auto c = client();
  for (const std::string host :
       {"127.0.0.1", "localhost:8080", "LOCALHOST", "[::1]:1234", "127.1.2.3:80"}) {
    auto res = c.Get("/jobs", {{"Host", host}});
    ASSERT_TRUE(res) << host;
    EXPECT_EQ(res->status, 200) << host;
  }
  for (const std::string host :
       {"evil.example", "evil.example:8080", "127.0.0.1.evil.example", "[::2]:80", "10.0.0.1"}) {
    auto res = c.Get("/jobs", {{"Host", host}});
    ASSERT_TRUE(res) << host;
    EXPECT_EQ(res->status, 403) << host;
    EXPECT_NE(res->body.find("not a loopback name"), std::string::npos) << res->body;
  }
}

TEST_F(HttpTest, TheTokenGuardsEveryDataRouteButNotThePageOrHealth) {
  HttpOptions o;
  o.token = "s3cret-token";
  start(o);
  for (const char* path : {"/jobs", "/jobs/j-1", "/jobs/j-1/samples", "/jobs/j-1/samples.csv",
                           "/jobs/j-1/snapshots/0.vtp", "/jobs/j-1/snapshots/latest.mesh",
                           "/results", "/metrics", "/nowhere"}) {
    auto res = client().Get(path);
    ASSERT_TRUE(res) << path;
    EXPECT_EQ(res->status, 401) << path;
    EXPECT_EQ(res->get_header_value("WWW-Authenticate"), "Bearer realm=\"foamd\"") << path;
    EXPECT_NE(res->body.find("Authorization: Bearer"), std::string::npos) << res->body;
    res = client("s3cret-tokeN").Get(path);
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 401) << path;
    EXPECT_NE(res->body.find("wrong token"), std::string::npos) << res->body;
  }
  auto res = client("s3cret-token").Get("/jobs");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(client("s3cret-token").Get("/metrics")->status, 200);
  // The page carries no data: the browser loads it, then asks for the token.
  for (const char* path : {"/healthz", "/", "/index.html", "/app.js", "/style.css", "/chart.js",
                           "/view3d.js", "/three.js", "/orbit-controls.js"}) {
    res = client().Get(path);
    ASSERT_TRUE(res) << path;
    EXPECT_EQ(res->status, 200) << path;
    EXPECT_FALSE(res->body.empty()) << path;
  }
  EXPECT_EQ(client().Get("/")->get_header_value("Content-Type"), "text/html; charset=utf-8");
  EXPECT_NE(client().Get("/chart.js")->body.find("Chart.js v3"), std::string::npos);
}

// `Range: bytes=0-9` got "200" with the first 10 bytes of the answer (cpp-httplib cut the body
// and kept the handler's status), and a 401 was cut to `{"error":"`. Every Range is ignored:
// each answer comes whole, with its own status, and says `Accept-Ranges: none`; a Range the
// library cannot parse (another unit, FIRST > LAST, a number beyond 64 bits) was 416 before any
// route, and is ignored too.
TEST_F(HttpTest, RangeRequestsGetTheWholeAnswer) {
  HttpOptions o;
  o.token = "s3cret-token-0123456789";
  start(o);
  const std::vector<std::string> ranges = {
      "bytes=0-9",     "bytes=5-",  "bytes=-3",  "bytes=0-0,5-9",
      "bytes=100000-", "bytes=5-2", "items=0-1", "bytes=99999999999999999999999-",
      "bytes=-"};
  struct Route {
    std::string path, token;
    int status;
  };
  const std::vector<Route> routes = {
      {"/healthz", "", 200},   {"/app.js", "", 200},
      {"/jobs", o.token, 200}, {"/jobs/j-none", o.token, 404},
      {"/jobs", "", 401},      {"/jobs", "wrong-token-0123456789", 401}};
  for (const Route& route : routes) {
    auto whole = client(route.token).Get(route.path);
    ASSERT_TRUE(whole) << route.path;
    ASSERT_EQ(whole->status, route.status) << route.path;
    EXPECT_EQ(whole->get_header_value("Accept-Ranges"), "none") << route.path;
    if (route.path != "/app.js") {
      EXPECT_TRUE(nlohmann::json::accept(whole->body)) << whole->body;
      EXPECT_GT(whole->body.size(), 10u) << whole->body;
    }
    for (const std::string& range : ranges) {
      auto res = client(route.token).Get(route.path, {{"Range", range}});
      ASSERT_TRUE(res) << route.path << " " << range;
      EXPECT_EQ(res->status, route.status) << route.path << " " << range << ": " << res->body;
      EXPECT_EQ(res->body, whole->body) << route.path << " " << range;
      EXPECT_FALSE(res->has_header("Content-Range")) << route.path << " " << range;
      EXPECT_EQ(res->get_header_value("Accept-Ranges"), "none") << route.path << " " << range;
    }
  }
  // HEAD too: the headers GET would have, no range.
  const RawAnswer head = rawExchange(
      http_->port(), "HEAD /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nRange: bytes=0-1\r\n\r\n");
  EXPECT_EQ(head.text.substr(0, 12), "HTTP/1.1 200") << head.text;
  EXPECT_NE(head.text.find("Accept-Ranges: none"), std::string::npos) << head.text;
  EXPECT_EQ(head.text.find("Content-Range"), std::string::npos) << head.text;
}

TEST_F(HttpTest, MetricsPublicOpensOnlyMetrics) {
  HttpOptions o;
  o.token = "s3cret-token";
  o.metrics_public = true;
  start(o);
  auto res = client().Get("/metrics");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_NE(res->body.find("foamd_queue_depth 0"), std::string::npos) << res->body;
  EXPECT_EQ(client().Get("/jobs")->status, 401);
  EXPECT_EQ(client().Get("/results")->status, 401);
}

TEST_F(HttpTest, TlsWithTheServersCertificate) {
  HttpOptions o;
  o.token = "s3cret-token";
  o.tls_cert_path = fs::path(SERVER_TEST_DATA) / "test-cert.pem";
  o.tls_key_path = fs::path(SERVER_TEST_DATA) / "test-key.pem";
  HttpEndpoint& http = start(o);
  httplib::SSLClient tls("127.0.0.1", http.port());
  tls.set_ca_cert_path(o.tls_cert_path.c_str());
  tls.enable_server_certificate_verification(true);
  tls.set_bearer_token_auth("s3cret-token");
  auto res = tls.Get("/jobs");
  ASSERT_TRUE(res) << httplib::to_string(res.error());
  EXPECT_EQ(res->status, 200);
  // Plain text to the TLS port gets no HTTP answer.
  auto plain = client("s3cret-token").Get("/jobs");
  EXPECT_TRUE(!plain || plain->status != 200);
}

TEST(HttpListener, NonLoopbackNeedsATokenAndTls) {
  HttpOptions o;
  o.listen = "0.0.0.0:8080";
  auto message = [](const HttpOptions& x) {
    try {
      checkHttpOptions(x);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  std::string m = message(o);
  EXPECT_NE(m.find("not a loopback address"), std::string::npos) << m;
  EXPECT_NE(m.find("--token-file"), std::string::npos) << m;
  EXPECT_NE(m.find("--tls-cert"), std::string::npos) << m;
  o.token = "t";
  EXPECT_FALSE(message(o).empty());  // a token in plain text is no better
  o.tls_cert_path = "c.pem";
  EXPECT_NE(message(o).find("both --tls-cert and --tls-key"), std::string::npos);
  o.tls_key_path = "k.pem";
  EXPECT_EQ(message(o), "");
  for (const char* loop : {"127.0.0.1:0", "localhost:8080", "[::1]:8080"}) {
    HttpOptions l;
    l.listen = loop;
    EXPECT_EQ(message(l), "") << loop;
  }
  HttpOptions t;
  t.listen = "127.0.0.1:0";
  t.threads = 2;
  EXPECT_NE(message(t).find("--http-threads 2: allowed range [4, 1024]"), std::string::npos);
  t.threads = 32;
  t.listen = "127.0.0.1";
  EXPECT_NE(message(t).find("expected HOST:PORT"), std::string::npos);
}

TEST(GrpcListener, NonLoopbackNeedsATokenOrInsecurePublic) {
  ServerConfig c;
  c.listen = "0.0.0.0:50051";
  try {
    checkServerConfig(c);
    ADD_FAILURE() << "a public listener without a token was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--insecure-public"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--token-file"), std::string::npos) << e.what();
  }
  c.insecure_public = true;
  EXPECT_NO_THROW(checkServerConfig(c));
  c.insecure_public = false;
  c.token = "t";
  EXPECT_THROW(checkServerConfig(c), std::invalid_argument);  // a token needs TLS there
  c.tls_cert = "PEM";
  c.tls_key = "PEM";
  EXPECT_NO_THROW(checkServerConfig(c));
  ServerConfig local;
  local.listen = "127.0.0.1:50051";
  EXPECT_NO_THROW(checkServerConfig(local));
}

// The refusals as a user meets them: foamd exits 2 before it opens the database.
TEST(Listeners, FoamdRefusesPublicAddressesWithoutProtection) {
  const fs::path dir = tempDir();
  const std::string foamd = std::string(FOAMD_EXE) + " --db " + (dir / "f.db").string();
  auto r = sh(foamd + " --listen 0.0.0.0:0 2>&1");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("--insecure-public"), std::string::npos) << r.out;
  r = sh(foamd + " --listen 127.0.0.1:0 --http 0.0.0.0:0 2>&1");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("--http 0.0.0.0:0 is not a loopback address"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(dir / "f.db"));
  // With --insecure-public it starts, and says so.
  r = sh("timeout --preserve-status -s TERM 2 " + foamd +
         " --listen 0.0.0.0:0 --insecure-public 2>&1");
  EXPECT_EQ(r.rc, 0) << r.out;
  EXPECT_NE(r.out.find("--insecure-public: gRPC on 0.0.0.0:0 with no token"), std::string::npos)
      << r.out;
  fs::remove_all(dir);
}
