// The database's lock (see DbLock in store.h).
#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>

#include <spdlog/spdlog.h>

#include "store.h"

namespace activefoam::server {

namespace {

std::string trimmed(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  return s;
}

// The database's canonical path: symlinks (of the file and of its directories) and relative
// parts resolved, so every alias of one file names the same ".lock" beside it.
std::string resolvedPath(const std::string& db_path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path p = fs::absolute(db_path, ec);
  if (ec) return db_path;
  const fs::path canon = fs::weakly_canonical(p, ec);  // follows the symlinks that exist
  return ec ? p.string() : canon.string();
}

// The pid holding a flock on (dev, ino), from /proc/locks; 0 when unknown.
long flockHolder(dev_t dev, ino_t ino) {
  std::ifstream in("/proc/locks");
  std::string line;
  std::ostringstream want;
  want << std::hex << std::setfill('0') << std::setw(2) << major(dev) << ':' << std::setw(2)
       << minor(dev) << ':' << std::dec << ino;
  while (std::getline(in, line)) {
    // "1: FLOCK  ADVISORY  WRITE 1234 08:01:5678 0 EOF"
    std::istringstream f(line);
    std::string num, kind, adv, mode, pid, id;
    if (!(f >> num >> kind >> adv >> mode >> pid >> id)) continue;
    if (kind == "FLOCK" && id == want.str()) return std::strtol(pid.c_str(), nullptr, 10);
  }
  return 0;
}

}  // namespace

DbLock::DbLock(const std::string& db_path) {
  // Two locks, both flock(2), released by the kernel when the process ends:
  // - on the database file itself, so that every name of it (a symlink, a hard link, a relative
  //   path, a directory symlink) meets the same lock: flock belongs to the file, not the name;
  //   SQLite's own locks are fcntl(2) byte ranges, which flock does not touch on Linux;
  // - on "<resolved db>.lock", which names the holder (pid, host, start time) for the error a
  //   second server gets, and which foamd versions before the file lock take.
  const std::string resolved = resolvedPath(db_path);
  const std::string lock_path = resolved + ".lock";
  fd_ = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0)
    throw std::runtime_error("cannot open lock file '" + lock_path + "': " + std::strerror(errno));
  auto refuse = [&](const std::string& holder, const std::string& how) {
    throw StoreError(StoreError::Kind::FailedPrecondition,
                     "database '" + db_path + "' is in use by another foamd (" +
                         (holder.empty() ? std::string("holder unknown") : holder) + "; " + how +
                         "): one server per database — stop it first, or give this one its own "
                         "--db");
  };
  auto holderText = [&] {
    char buf[256];
    const ssize_t n = ::pread(fd_, buf, sizeof buf - 1, 0);
    return n > 0 ? trimmed(std::string(buf, static_cast<std::size_t>(n))) : std::string();
  };
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    const std::string holder = holderText();
    ::close(fd_);
    fd_ = -1;
    if (err != EWOULDBLOCK)
      throw std::runtime_error("cannot lock '" + lock_path + "': " + std::strerror(err));
    refuse(holder, "lock " + lock_path);
  }
  db_fd_ = ::open(resolved.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (db_fd_ < 0) {
    const int err = errno;
    ::close(fd_);
    fd_ = -1;
    throw std::runtime_error("cannot open database '" + db_path + "': " + std::strerror(err));
  }
  if (::flock(db_fd_, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    struct stat st {};
    const long pid = ::fstat(db_fd_, &st) == 0 ? flockHolder(st.st_dev, st.st_ino) : 0;
    ::close(db_fd_);
    ::close(fd_);
    db_fd_ = fd_ = -1;
    if (err != EWOULDBLOCK)
      throw std::runtime_error("cannot lock '" + resolved + "': " + std::strerror(err));
    refuse(pid > 0 ? "pid " + std::to_string(pid) : std::string(),
           "it holds the database file " + resolved + " through another name (a hard link?)");
  }
  char host[256] = "?";
  ::gethostname(host, sizeof host - 1);
  const std::string who =
      "pid " + std::to_string(::getpid()) + " on " + host + ", since " + utcNowText() + "\n";
  if (::ftruncate(fd_, 0) != 0 || ::pwrite(fd_, who.data(), who.size(), 0) < 0)
    spdlog::warn("store: cannot record the holder in '{}': {}", lock_path, std::strerror(errno));
}

DbLock::~DbLock() {
  if (db_fd_ >= 0) ::close(db_fd_);  // releases the flocks
  if (fd_ >= 0) ::close(fd_);
}

}  // namespace activefoam::server
