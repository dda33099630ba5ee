// foamd and foam as processes, for the tests that drive them from outside (tests/server's CLI
// tests, tests/faults). The including target defines FOAMD_EXE and FOAM_EXE.
#pragma once

#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace activefoam::testing {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

inline int freePort() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t len = sizeof a;
  getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  close(fd);
  return ntohs(a.sin_port);
}

struct Proc {
  int rc = -1;
  std::string out;
};

// Runs a shell command; stdout captured, stderr to the given file.
inline Proc sh(const std::string& cmd) {
  Proc r;
  FILE* p = popen(cmd.c_str(), "r");
  char buf[4096];
  std::size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) r.out.append(buf, n);
  const int st = pclose(p);
  r.rc = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

class Foamd {
 public:
  Foamd(fs::path db, int port, int workers = 1, std::vector<std::string> extra = {})
      : db_(std::move(db)), port_(port), workers_(workers), extra_(std::move(extra)) {
    start();
  }
  ~Foamd() { stop(SIGTERM); }
  void start() {
    pid_ = fork();
    if (pid_ == 0) {
      // foamd as a shell starts it: default dispositions, nothing blocked (an ignored SIGPIPE
      // of the test's parent would pass on through exec and hide foamd's own handling).
      for (int sig = 1; sig < NSIG; ++sig)
        if (sig != SIGKILL && sig != SIGSTOP) ::signal(sig, SIG_DFL);
      sigset_t none;
      sigemptyset(&none);
      sigprocmask(SIG_SETMASK, &none, nullptr);
      const std::string listen = "127.0.0.1:" + std::to_string(port_);
      const std::string log = (db_.parent_path() / "foamd.log").string();
      freopen(log.c_str(), "a", stderr);
      freopen(log.c_str(), "a", stdout);
      const std::string workers = std::to_string(workers_);
      std::vector<const char*> argv{FOAMD_EXE,   "--listen",  listen.c_str(), "--db",
                                    db_.c_str(), "--workers", workers.c_str()};
      for (const std::string& e : extra_) argv.push_back(e.c_str());
      argv.push_back(nullptr);
      execv(FOAMD_EXE, const_cast<char* const*>(argv.data()));
      _exit(127);
    }
  }
  // The exit status once the process has ended by itself within `timeout` (nullopt: still
  // running).
  std::optional<int> exited(std::chrono::milliseconds timeout) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    while (pid_ > 0) {
      int st = 0;
      if (waitpid(pid_, &st, WNOHANG) == pid_) {
        pid_ = -1;
        return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
      }
      if (std::chrono::steady_clock::now() > until) return std::nullopt;
      std::this_thread::sleep_for(20ms);
    }
    return std::nullopt;
  }
  pid_t pid() const { return pid_; }
  void stop(int sig) {
    if (pid_ <= 0) return;
    kill(pid_, sig);
    int st = 0;
    waitpid(pid_, &st, 0);
    pid_ = -1;
  }
  std::string foam() const {
    return std::string(FOAM_EXE) + " --server 127.0.0.1:" + std::to_string(port_);
  }

 private:
  fs::path db_;
  int port_;
  int workers_;
  std::vector<std::string> extra_;
  pid_t pid_ = -1;
};

inline fs::path tempDir() {
  static std::mt19937_64 rng{std::random_device{}()};
  const fs::path d = fs::temp_directory_path() / ("foam-cli-test-" + std::to_string(rng()));
  fs::create_directories(d);
  return d;
}

inline std::string firstLine(const std::string& s) {
  return s.substr(0, s.find('\n'));
}

// foam show ID → the state (first line); retries while the server starts.
inline std::string state(const Foamd& d, const std::string& id) {
  for (int i = 0; i < 100; ++i) {
    const Proc r = sh(d.foam() + " show " + id + " 2>/dev/null");
    if (r.rc == 0) return firstLine(r.out);
    std::this_thread::sleep_for(100ms);
  }
  return "";
}

}  // namespace activefoam::testing
