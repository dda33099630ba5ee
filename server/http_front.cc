// The accept side of foamd's HTTP endpoint (see http_front.h).
#include "http_front.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <openssl/err.h>
#include <openssl/ssl.h>
#include <poll.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <climits>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <list>
#include <stdexcept>
#include <vector>

#include <spdlog/spdlog.h>

#include <httplib.h>

namespace activefoam::server {

using Clock = std::chrono::steady_clock;

namespace {

constexpr std::size_t kMaxHead = 64 * 1024;  // handed on unfinished: the library answers 414/431
constexpr int kAcceptsPerTurn = 16;          // then the ready connections are read

std::string ipOf(const sockaddr_storage& sa, int& port) {
  char buf[INET6_ADDRSTRLEN] = "";
  if (sa.ss_family == AF_INET) {
    const auto& a = reinterpret_cast<const sockaddr_in&>(sa);
    inet_ntop(AF_INET, &a.sin_addr, buf, sizeof buf);
    port = ntohs(a.sin_port);
  } else if (sa.ss_family == AF_INET6) {
    const auto& a = reinterpret_cast<const sockaddr_in6&>(sa);
    inet_ntop(AF_INET6, &a.sin6_addr, buf, sizeof buf);
    port = ntohs(a.sin6_port);
  }
  return buf;
}

// A whole answer that closes the connection, for the front's own refusals.
std::string closingAnswer(const char* status, const std::string& error) {
  const std::string body = "{\"error\":\"" + error + "\"}";
  return std::string("HTTP/1.1 ") + status +
         "\r\nConnection: close\r\nContent-Type: application/json\r\nContent-Length: " +
         std::to_string(body.size()) + "\r\n\r\n" + body;
}
const std::string kTimedOut =
    closingAnswer("408 Request Timeout", "the request header did not arrive in time");
const std::string kBusy =
    closingAnswer("503 Service Unavailable", "too many connections from your address");

bool headerComplete(const std::string& head) {
  return head.find("\r\n\r\n") != std::string::npos || head.find("\n\n") != std::string::npos;
}

bool isHealth(const std::string& head) {
  for (const char* m : {"GET /healthz", "HEAD /healthz"}) {
    const std::size_t n = std::strlen(m);
    if (head.compare(0, n, m) == 0 && head.size() > n && (head[n] == ' ' || head[n] == '?'))
      return true;
  }
  return false;
}

// Waits until `fd` is ready for `events` or `ms` passed (ms < 0: at once).
bool waitFor(int fd, short events, int ms) {
  pollfd p{fd, events, 0};
  for (;;) {
    const int r = ::poll(&p, 1, std::max(ms, 0));
    if (r < 0 && errno == EINTR) continue;
    return r > 0;
  }
}

int msUntil(Clock::time_point t) {
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(t - Clock::now()).count();
  return static_cast<int>(std::clamp<long long>(ms, 0, INT_MAX));
}

}  // namespace

int bindHttpListener(const std::string& host, int& port) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
  addrinfo* list = nullptr;
  const std::string service = std::to_string(port);
  if (::getaddrinfo(host.empty() ? nullptr : host.c_str(), service.c_str(), &hints, &list) != 0)
    return -1;
  int fd = -1;
  for (addrinfo* a = list; a != nullptr && fd < 0; a = a->ai_next) {
    fd = ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC | SOCK_NONBLOCK, a->ai_protocol);
    if (fd < 0) continue;
    int yes = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
    if (::bind(fd, a->ai_addr, a->ai_addrlen) != 0 || ::listen(fd, 1024) != 0) {
      ::close(fd);
      fd = -1;
    }
  }
  ::freeaddrinfo(list);
  if (fd < 0) return -1;
  sockaddr_storage sa{};
  socklen_t len = sizeof sa;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&sa), &len);
  (void)ipOf(sa, port);
  return fd;
}

struct HttpFront::Conn {
  int fd = -1;
  SSL* ssl = nullptr;
  bool handshaken = false;
  bool dead = false;
  std::string addr;  // the client's address: what the per-client count is kept by
  int port = 0;
  std::string head;  // read before the header was complete; the library reads it first
  Clock::time_point deadline;
  std::list<std::unique_ptr<Conn>>::iterator at;  // in the waiting list
  HttpFront* front = nullptr;

  ~Conn() {
    if (ssl != nullptr) {
      if (handshaken) (void)SSL_shutdown(ssl);  // best effort: the socket is non-blocking
      SSL_free(ssl);
    }
    if (fd >= 0) {
      ::shutdown(fd, SHUT_RDWR);
      ::close(fd);
    }
    if (front != nullptr) front->release(addr);
  }
};

// The connections sending their headers, oldest (first deadline) first.
struct HttpFront::Waiting {
  std::list<std::unique_ptr<Conn>> list;
  std::vector<std::unique_ptr<Conn>> graveyard;  // freed after the epoll turn that dropped them
};

namespace {

// One connection as the library sees it: what the front read first, then the socket, each read
// before `read_deadline`, each write within the I/O timeout.
class ConnStream final : public httplib::Stream {
 public:
  ConnStream(int fd, SSL* ssl, const std::string& head, std::string ip, int port,
             Clock::time_point read_deadline, int write_ms)
      : fd_(fd),
        ssl_(ssl),
        head_(head),
        ip_(std::move(ip)),
        port_(port),
        read_deadline_(read_deadline),
        write_ms_(write_ms) {}

  bool is_readable() const override {
    if (pos_ < head_.size() || (ssl_ != nullptr && SSL_pending(ssl_) > 0)) return true;
    return waitFor(fd_, POLLIN, msUntil(read_deadline_));
  }
  bool is_writable() const override { return waitFor(fd_, POLLOUT, write_ms_); }

  ssize_t read(char* ptr, size_t size) override {
    if (pos_ < head_.size()) {
      const std::size_t n = std::min(size, head_.size() - pos_);
      std::memcpy(ptr, head_.data() + pos_, n);
      pos_ += n;
      return static_cast<ssize_t>(n);
    }
    const int n = static_cast<int>(std::min<size_t>(size, INT_MAX));
    for (;;) {
      short want = POLLIN;
      if (ssl_ != nullptr) {
        const int r = SSL_read(ssl_, ptr, n);
        if (r > 0) return r;
        const int e = SSL_get_error(ssl_, r);
        if (e == SSL_ERROR_ZERO_RETURN) return 0;
        if (e == SSL_ERROR_WANT_WRITE)
          want = POLLOUT;
        else if (e != SSL_ERROR_WANT_READ)
          return -1;
      } else {
        const ssize_t r = ::recv(fd_, ptr, static_cast<size_t>(n), 0);
        if (r >= 0) return r;
        if (errno == EINTR) continue;
        if (errno != EAGAIN && errno != EWOULDBLOCK) return -1;
      }
      if (Clock::now() >= read_deadline_ || !waitFor(fd_, want, msUntil(read_deadline_))) return -1;
    }
  }

  ssize_t write(const char* ptr, size_t size) override {
    const int n = static_cast<int>(std::min<size_t>(size, INT_MAX));
    const auto deadline = Clock::now() + std::chrono::milliseconds(write_ms_);
    for (;;) {
      short want = POLLOUT;
      if (ssl_ != nullptr) {
        const int r = SSL_write(ssl_, ptr, n);
        if (r > 0) return r;
        const int e = SSL_get_error(ssl_, r);
        if (e == SSL_ERROR_WANT_READ)
          want = POLLIN;
        else if (e != SSL_ERROR_WANT_WRITE)
          return -1;
      } else {
        const ssize_t r = ::send(fd_, ptr, static_cast<size_t>(n), MSG_NOSIGNAL);
        if (r >= 0) return r;
        if (errno == EINTR) continue;
        if (errno != EAGAIN && errno != EWOULDBLOCK) return -1;
      }
      if (Clock::now() >= deadline || !waitFor(fd_, want, msUntil(deadline))) return -1;
    }
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    ip = ip_;
    port = port_;
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage sa{};
    socklen_t len = sizeof sa;
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&sa), &len);
    ip = ipOf(sa, port);
  }
  socket_t socket() const override { return fd_; }

 private:
  int fd_;
  SSL* ssl_;
  const std::string& head_;
  std::size_t pos_ = 0;
  std::string ip_;
  int port_;
  Clock::time_point read_deadline_;
  int write_ms_;
};

}  // namespace

// Workers that answer whole requests, in arrival order.
struct HttpFront::Lane {
  std::mutex mu;
  std::condition_variable cv;
  std::deque<std::unique_ptr<Conn>> queue;
  bool stop = false;
  std::vector<std::thread> threads;

  Lane(int n, const Serve& serve, int io_timeout_s) {
    for (int k = 0; k < n; ++k)
      threads.emplace_back([this, &serve, io_timeout_s] {
        for (;;) {
          std::unique_ptr<Conn> c;
          {
            std::unique_lock<std::mutex> lock(mu);
            cv.wait(lock, [this] { return stop || !queue.empty(); });
            if (stop) return;
            c = std::move(queue.front());
            queue.pop_front();
          }
          ConnStream s(c->fd, c->ssl, c->head, c->addr, c->port,
                       Clock::now() + std::chrono::seconds(io_timeout_s), io_timeout_s * 1000);
          try {
            serve(s);
          } catch (const std::exception& e) {
            spdlog::warn("foamd: HTTP: a request failed: {}", e.what());
          }
        }
      });
  }
  void push(std::unique_ptr<Conn> c) {
    {
      std::lock_guard<std::mutex> lock(mu);
      queue.push_back(std::move(c));
    }
    cv.notify_one();
  }
  ~Lane() {
    {
      std::lock_guard<std::mutex> lock(mu);
      stop = true;
    }
    cv.notify_all();
    for (auto& t : threads) t.join();
  }
};

HttpFront::HttpFront(int listen_fd, SSL_CTX* tls, FrontOptions options, Serve serve)
    : listen_fd_(listen_fd),
      tls_(tls),
      options_(options),
      serve_(std::move(serve)),
      waiting_(std::make_unique<Waiting>()) {
  epoll_fd_ = ::epoll_create1(EPOLL_CLOEXEC);
  wake_fd_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  reserve_fd_ = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
  if (epoll_fd_ < 0 || wake_fd_ < 0) {
    const std::string why = std::strerror(errno);
    for (int fd : {listen_fd_, epoll_fd_, wake_fd_, reserve_fd_})
      if (fd >= 0) ::close(fd);
    throw std::runtime_error("--http: epoll: " + why);
  }
  epoll_event ev{};
  ev.events = EPOLLIN;
  ev.data.ptr = &listen_fd_;
  ::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, listen_fd_, &ev);
  ev.data.ptr = &wake_fd_;
  ::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, wake_fd_, &ev);
  general_ = std::make_unique<Lane>(options_.workers, serve_, options_.io_timeout_s);
  health_ = std::make_unique<Lane>(1, serve_, options_.io_timeout_s);
  thread_ = std::thread([this] { loop(); });
}

HttpFront::~HttpFront() {
  stopping_ = true;
  const std::uint64_t one = 1;
  (void)!::write(wake_fd_, &one, sizeof one);
  if (thread_.joinable()) thread_.join();
  waiting_->list.clear();
  waiting_->graveyard.clear();
  general_.reset();  // waits for the requests being answered; drops the queued ones
  health_.reset();
  for (int fd : {listen_fd_, epoll_fd_, wake_fd_, reserve_fd_})
    if (fd >= 0) ::close(fd);
}

void HttpFront::release(const std::string& addr) {
  std::lock_guard<std::mutex> lock(count_mu_);
  --total_;
  if (auto it = per_client_.find(addr); it != per_client_.end() && --it->second <= 0)
    per_client_.erase(it);
}

int HttpFront::total() {
  std::lock_guard<std::mutex> lock(count_mu_);
  return total_;
}

int HttpFront::held(const std::string& addr) {
  std::lock_guard<std::mutex> lock(count_mu_);
  const auto it = per_client_.find(addr);
  return it == per_client_.end() ? 0 : it->second;
}

void HttpFront::loop() {
  epoll_event events[64];
  while (!stopping_) {
    int timeout = -1;
    if (!waiting_->list.empty()) timeout = msUntil(waiting_->list.front()->deadline) + 1;
    const int n = ::epoll_wait(epoll_fd_, events, 64, timeout);
    if (n < 0 && errno != EINTR) {
      spdlog::error("foamd: HTTP: epoll_wait: {}", std::strerror(errno));
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    for (int k = 0; k < n; ++k) {
      void* p = events[k].data.ptr;
      if (p == &wake_fd_) continue;
      if (p == &listen_fd_)
        acceptSome();
      else
        onReady(static_cast<Conn*>(p));
    }
    // The header deadline: the oldest first, so the list is in deadline order.
    const auto now = Clock::now();
    while (!waiting_->list.empty() && waiting_->list.front()->deadline <= now)
      drop(waiting_->list.front().get(), kTimedOut.c_str());
    waiting_->graveyard.clear();
  }
}

// Closes a connection still sending its header (`answer`, if any, is sent first, best effort:
// never on TLS, whose records the front does not write).
void HttpFront::drop(Conn* c, const char* answer) {
  if (c->dead) return;
  c->dead = true;
  ::epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, c->fd, nullptr);
  if (answer != nullptr && c->ssl == nullptr)
    (void)!::send(c->fd, answer, std::strlen(answer), MSG_NOSIGNAL | MSG_DONTWAIT);
  waiting_->graveyard.push_back(std::move(*c->at));
  waiting_->list.erase(c->at);
}

// Closes the oldest connection still sending its header, of `addr` or of any client.
bool HttpFront::evictOldest(const std::string* addr) {
  for (auto& c : waiting_->list)
    if (!c->dead && (addr == nullptr || c->addr == *addr)) {
      drop(c.get(), nullptr);
      return true;
    }
  return false;
}

void HttpFront::acceptSome() {
  for (int k = 0; k < kAcceptsPerTurn; ++k) {
    sockaddr_storage sa{};
    socklen_t len = sizeof sa;
    const int fd =
        ::accept4(listen_fd_, reinterpret_cast<sockaddr*>(&sa), &len, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) {
      if (errno == EINTR || errno == ECONNABORTED) continue;
      if (errno == EMFILE || errno == ENFILE) {
        // Out of descriptors: make room by the oldest header still coming, or accept and close
        // with the one held in reserve, so the kernel's queue does not spin the loop.
        if (evictOldest(nullptr)) continue;
        if (reserve_fd_ >= 0) {
          ::close(reserve_fd_);
          const int drop_fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC);
          if (drop_fd >= 0) ::close(drop_fd);
          reserve_fd_ = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
        }
      }
      return;  // EAGAIN: all accepted
    }
    auto c = std::make_unique<Conn>();
    c->fd = fd;
    c->addr = ipOf(sa, c->port);
    // The limits: make room by the oldest header still coming, of this client, then of any
    // (a connection dropped now is counted until the end of this turn: one each time).
    const bool room = (held(c->addr) < options_.max_per_client || evictOldest(&c->addr)) &&
                      (total() < options_.max_connections || evictOldest(nullptr));
    if (!room) {
      if (tls_ == nullptr)
        (void)!::send(fd, kBusy.data(), kBusy.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
      continue;  // ~Conn closes it; it was never counted
    }
    {
      std::lock_guard<std::mutex> lock(count_mu_);
      ++per_client_[c->addr];
      ++total_;
    }
    c->front = this;
    c->deadline = Clock::now() + std::chrono::seconds(options_.header_timeout_s);
    if (tls_ != nullptr) {
      c->ssl = SSL_new(tls_);
      if (c->ssl == nullptr || SSL_set_fd(c->ssl, fd) != 1) continue;
      SSL_set_accept_state(c->ssl);
    }
    Conn* raw = c.get();
    waiting_->list.push_back(std::move(c));
    raw->at = std::prev(waiting_->list.end());
    epoll_event ev{};
    ev.events = EPOLLIN;
    ev.data.ptr = raw;
    if (::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, fd, &ev) != 0) {
      drop(raw, nullptr);
      continue;
    }
    onReady(raw);  // a client that wrote at once is answered without waiting a turn
  }
}

void HttpFront::onReady(Conn* c) {
  if (c->dead) return;
  auto wantWrite = [&](bool out) {
    epoll_event ev{};
    ev.events = EPOLLIN | (out ? EPOLLOUT : 0u);
    ev.data.ptr = c;
    ::epoll_ctl(epoll_fd_, EPOLL_CTL_MOD, c->fd, &ev);
  };
  if (c->ssl != nullptr && !c->handshaken) {
    ERR_clear_error();
    const int r = SSL_accept(c->ssl);
    if (r != 1) {
      const int e = SSL_get_error(c->ssl, r);
      if (e == SSL_ERROR_WANT_READ || e == SSL_ERROR_WANT_WRITE)
        wantWrite(e == SSL_ERROR_WANT_WRITE);
      else
        drop(c, nullptr);  // not TLS, or a failed handshake
      return;
    }
    c->handshaken = true;
    wantWrite(false);
  }
  char buf[16 * 1024];
  for (;;) {
    if (c->ssl != nullptr) {
      ERR_clear_error();
      const int r = SSL_read(c->ssl, buf, sizeof buf);
      if (r > 0) {
        c->head.append(buf, static_cast<std::size_t>(r));
      } else {
        const int e = SSL_get_error(c->ssl, r);
        if (e == SSL_ERROR_WANT_READ || e == SSL_ERROR_WANT_WRITE) {
          wantWrite(e == SSL_ERROR_WANT_WRITE);
          return;
        }
        drop(c, nullptr);
        return;
      }
    } else {
      const ssize_t r = ::recv(c->fd, buf, sizeof buf, 0);
      if (r > 0) {
        c->head.append(buf, static_cast<std::size_t>(r));
      } else if (r < 0 && errno == EINTR) {
        continue;
      } else if (r < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
        return;
      } else {
        drop(c, nullptr);  // closed before a whole header
        return;
      }
    }
    if (headerComplete(c->head) || c->head.size() >= kMaxHead) {
      handOff(c);
      return;
    }
  }
}

void HttpFront::handOff(Conn* c) {
  ::epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, c->fd, nullptr);
  std::unique_ptr<Conn> own = std::move(*c->at);
  waiting_->list.erase(c->at);
  Lane& lane = isHealth(own->head) ? *health_ : *general_;
  lane.push(std::move(own));
}

}  // namespace activefoam::server
