// Study drivers run each configuration in a forked child: a blow-up or crash cannot take the
// study down, and the child's peak memory is its own (wait4's rusage).
#pragma once

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <optional>
#include <type_traits>

namespace activefoam::bench {

// Runs f() in a child and returns its result (plain data, sent back through a pipe), or nullopt
// when the child died or exited otherwise. peak_rss_mb, when given, receives the child's peak RSS.
template <class F>
auto runForked(F&& f, double* peak_rss_mb = nullptr) -> std::optional<decltype(f())> {
  using Out = decltype(f());
  static_assert(std::is_trivially_copyable_v<Out>, "the result crosses a pipe");
  int fds[2];
  if (pipe(fds) != 0) std::exit(1);
  const pid_t pid = fork();
  if (pid == 0) {
    close(fds[0]);
    const Out out = f();
    _exit(write(fds[1], &out, sizeof out) == static_cast<ssize_t>(sizeof out) ? 0 : 1);
  }
  close(fds[1]);
  Out out{};
  const ssize_t got = read(fds[0], &out, sizeof out);
  close(fds[0]);
  int status = 0;
  rusage ru{};
  wait4(pid, &status, 0, &ru);
  if (peak_rss_mb) *peak_rss_mb = static_cast<double>(ru.ru_maxrss) / 1024.0;
  if (got != static_cast<ssize_t>(sizeof out) || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
    return std::nullopt;
  return out;
}

}  // namespace activefoam::bench
