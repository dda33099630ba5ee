// The database's lock file (see DbLock in store.h).
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstring>

#include <spdlog/spdlog.h>

#include "store.h"

namespace activefoam::server {

DbLock::DbLock(const std::string& db_path) {
  const std::string lock_path = db_path + ".lock";
  fd_ = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0)
    throw std::runtime_error("cannot open lock file '" + lock_path + "': " + std::strerror(errno));
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    std::string holder;
    char buf[256];
    const ssize_t n = ::pread(fd_, buf, sizeof buf - 1, 0);
    if (n > 0) holder.assign(buf, static_cast<std::size_t>(n));
    while (!holder.empty() && std::isspace(static_cast<unsigned char>(holder.back())))
      holder.pop_back();
    ::close(fd_);
    fd_ = -1;
    if (err != EWOULDBLOCK)
      throw std::runtime_error("cannot lock '" + lock_path + "': " + std::strerror(err));
    throw StoreError(StoreError::Kind::FailedPrecondition,
                     "database '" + db_path + "' is in use by another foamd (" +
                         (holder.empty() ? std::string("holder unknown") : holder) + "; lock " +
                         lock_path +
                         "): one server per database — stop it first, or give this one its own "
                         "--db");
  }
  char host[256] = "?";
  ::gethostname(host, sizeof host - 1);
  const std::string who =
      "pid " + std::to_string(::getpid()) + " on " + host + ", since " + utcNowText() + "\n";
  if (::ftruncate(fd_, 0) != 0 || ::pwrite(fd_, who.data(), who.size(), 0) < 0)
    spdlog::warn("store: cannot record the holder in '{}': {}", lock_path, std::strerror(errno));
}

DbLock::~DbLock() {
  if (fd_ >= 0) ::close(fd_);  // releases the flock
}

}  // namespace activefoam::server
