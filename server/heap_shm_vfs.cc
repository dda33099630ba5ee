// The store's VFS with the WAL index in the heap (see heap_shm_vfs.h).
#include "heap_shm_vfs.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace activefoam::server::sql {
namespace {

// SQLite's layout of the -shm file (os_unix.c): 8 lock bytes from 120, then the DMS byte.
constexpr off_t kDmsByte = 120 + SQLITE_SHM_NLOCK;

struct File;

// One database's index, shared by this process's connections to it.
struct Index {
  std::vector<void*> regions;  // each calloc'ed, never moved
  std::vector<File*> users;
  int guard_fd = -1;  // <db>-shm, write-locked on its DMS byte
};

std::mutex g_mu;  // every Index and every File's masks
std::map<std::string, Index*> g_indexes;

struct File {
  sqlite3_file base;
  std::string* key;  // the database's identity (main database files only)
  Index* index;
  std::uint16_t shared_mask, excl_mask;
  sqlite3_file* real;  // the underlying VFS's file, allocated right after this struct
};

sqlite3_file* inner(sqlite3_file* f) {
  return reinterpret_cast<File*>(f)->real;
}

int xShmUnmap(sqlite3_file* f, int);

int xClose(sqlite3_file* f) {
  File* p = reinterpret_cast<File*>(f);
  if (p->index != nullptr) xShmUnmap(f, 0);
  delete p->key;
  p->key = nullptr;
  return inner(f)->pMethods->xClose(inner(f));
}
int xRead(sqlite3_file* f, void* b, int n, sqlite3_int64 off) {
  return inner(f)->pMethods->xRead(inner(f), b, n, off);
}
int xWrite(sqlite3_file* f, const void* b, int n, sqlite3_int64 off) {
  return inner(f)->pMethods->xWrite(inner(f), b, n, off);
}
int xTruncate(sqlite3_file* f, sqlite3_int64 size) {
  return inner(f)->pMethods->xTruncate(inner(f), size);
}
int xSync(sqlite3_file* f, int flags) {
  return inner(f)->pMethods->xSync(inner(f), flags);
}
int xFileSize(sqlite3_file* f, sqlite3_int64* size) {
  return inner(f)->pMethods->xFileSize(inner(f), size);
}
int xLock(sqlite3_file* f, int l) {
  return inner(f)->pMethods->xLock(inner(f), l);
}
int xUnlock(sqlite3_file* f, int l) {
  return inner(f)->pMethods->xUnlock(inner(f), l);
}
int xCheckReservedLock(sqlite3_file* f, int* out) {
  return inner(f)->pMethods->xCheckReservedLock(inner(f), out);
}
int xFileControl(sqlite3_file* f, int op, void* arg) {
  return inner(f)->pMethods->xFileControl(inner(f), op, arg);
}
int xSectorSize(sqlite3_file* f) {
  return inner(f)->pMethods->xSectorSize(inner(f));
}
int xDeviceCharacteristics(sqlite3_file* f) {
  return inner(f)->pMethods->xDeviceCharacteristics(inner(f));
}

// Region `page` of the index (`size` bytes each), made when `extend`; null when absent.
int xShmMap(sqlite3_file* f, int page, int size, int extend, void volatile** out) {
  File* p = reinterpret_cast<File*>(f);
  *out = nullptr;
  if (p->key == nullptr) return SQLITE_IOERR_SHMOPEN;
  std::lock_guard lock(g_mu);
  if (p->index == nullptr) {
    Index*& index = g_indexes[*p->key];
    if (index == nullptr) {
      auto made = std::make_unique<Index>();
      // Keep other processes out (see the header): the lock SQLite's own index takes first.
      const std::string shm = p->key->substr(p->key->find('|') + 1) + "-shm";
      made->guard_fd = ::open(shm.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
      if (made->guard_fd >= 0) {
        struct flock fl {};
        fl.l_type = F_WRLCK;
        fl.l_whence = SEEK_SET;
        fl.l_start = kDmsByte;
        fl.l_len = 1;
        if (::fcntl(made->guard_fd, F_SETLK, &fl) != 0) {
          ::close(made->guard_fd);
          g_indexes.erase(*p->key);
          return SQLITE_BUSY;  // another process has the database open
        }
      }
      index = made.release();
    }
    p->index = index;
    index->users.push_back(p);
  }
  Index& index = *p->index;
  if (static_cast<std::size_t>(page) >= index.regions.size()) {
    if (!extend) return SQLITE_OK;
    while (index.regions.size() <= static_cast<std::size_t>(page)) {
      void* r = std::calloc(1, static_cast<std::size_t>(size));
      if (r == nullptr) return SQLITE_NOMEM;
      index.regions.push_back(r);
    }
  }
  *out = index.regions[static_cast<std::size_t>(page)];
  return SQLITE_OK;
}

// SQLite's rules between connections (os_unix.c unixShmLock): a shared lock conflicts with
// another connection's exclusive one, an exclusive lock with any other connection's lock.
int xShmLock(sqlite3_file* f, int offset, int n, int flags) {
  File* p = reinterpret_cast<File*>(f);
  if (p->index == nullptr || offset < 0 || n < 1 || offset + n > SQLITE_SHM_NLOCK)
    return SQLITE_IOERR_SHMLOCK;
  const auto mask = static_cast<std::uint16_t>(((1u << (offset + n)) - 1) & ~((1u << offset) - 1));
  std::lock_guard lock(g_mu);
  if (flags & SQLITE_SHM_UNLOCK) {
    if (flags & SQLITE_SHM_SHARED)
      p->shared_mask &= static_cast<std::uint16_t>(~mask);
    else
      p->excl_mask &= static_cast<std::uint16_t>(~mask);
    return SQLITE_OK;
  }
  const bool shared = (flags & SQLITE_SHM_SHARED) != 0;
  for (const File* o : p->index->users) {
    if (o == p) continue;
    if ((o->excl_mask & mask) != 0 || (!shared && (o->shared_mask & mask) != 0)) return SQLITE_BUSY;
  }
  if (shared)
    p->shared_mask |= mask;
  else
    p->excl_mask |= mask;
  return SQLITE_OK;
}

void xShmBarrier(sqlite3_file*) {
  std::atomic_thread_fence(std::memory_order_seq_cst);
  std::lock_guard lock(g_mu);
}

int xShmUnmap(sqlite3_file* f, int) {
  File* p = reinterpret_cast<File*>(f);
  std::lock_guard lock(g_mu);
  Index* index = p->index;
  if (index == nullptr) return SQLITE_OK;
  p->index = nullptr;
  p->shared_mask = p->excl_mask = 0;
  index->users.erase(std::remove(index->users.begin(), index->users.end(), p), index->users.end());
  if (index->users.empty()) {
    for (void* r : index->regions) std::free(r);
    if (index->guard_fd >= 0) ::close(index->guard_fd);  // releases the DMS lock
    g_indexes.erase(*p->key);
    delete index;
  }
  return SQLITE_OK;
}

// Version 2: the shared-memory methods, no xFetch/xUnfetch (no memory-mapped database reads).
const sqlite3_io_methods kMethods = {2,
                                     xClose,
                                     xRead,
                                     xWrite,
                                     xTruncate,
                                     xSync,
                                     xFileSize,
                                     xLock,
                                     xUnlock,
                                     xCheckReservedLock,
                                     xFileControl,
                                     xSectorSize,
                                     xDeviceCharacteristics,
                                     xShmMap,
                                     xShmLock,
                                     xShmBarrier,
                                     xShmUnmap,
                                     nullptr,
                                     nullptr};

struct Shim {
  sqlite3_vfs vfs;
  sqlite3_vfs* base;
  std::string name;
};

int xOpen(sqlite3_vfs* vfs, sqlite3_filename name, sqlite3_file* f, int flags, int* out_flags) {
  sqlite3_vfs* base = static_cast<Shim*>(vfs->pAppData)->base;
  File* p = reinterpret_cast<File*>(f);
  p->key = nullptr;
  p->index = nullptr;
  p->shared_mask = p->excl_mask = 0;
  p->real = reinterpret_cast<sqlite3_file*>(p + 1);
  const int rc = base->xOpen(base, name, p->real, flags, out_flags);
  if (rc != SQLITE_OK) {
    p->base.pMethods = nullptr;  // SQLite calls no method of a file that did not open
    return rc;
  }
  if ((flags & SQLITE_OPEN_MAIN_DB) != 0 && name != nullptr) {
    // The identity of the file (device and inode), then the path the -shm goes beside.
    struct stat st {};
    const std::string path = name;
    const std::string id = ::stat(path.c_str(), &st) == 0
                               ? std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino)
                               : path;
    p->key = new std::string(id + "|" + path);
  }
  p->base.pMethods = &kMethods;
  return SQLITE_OK;
}

int xDelete(sqlite3_vfs* v, const char* n, int sync) {
  sqlite3_vfs* b = static_cast<Shim*>(v->pAppData)->base;
  return b->xDelete(b, n, sync);
}
int xAccess(sqlite3_vfs* v, const char* n, int flags, int* out) {
  sqlite3_vfs* b = static_cast<Shim*>(v->pAppData)->base;
  return b->xAccess(b, n, flags, out);
}
int xFullPathname(sqlite3_vfs* v, const char* n, int size, char* out) {
  sqlite3_vfs* b = static_cast<Shim*>(v->pAppData)->base;
  return b->xFullPathname(b, n, size, out);
}
void* xDlOpen(sqlite3_vfs* v, const char* n) {
  sqlite3_vfs* b = static_cast<Shim*>(v->pAppData)->base;
  return b->xDlOpen(b, n);
}
void xDlError(sqlite3_vfs* v, int n, char* msg) {
  sqlite3_vfs* b = static_cast<Shim*>(v->pAppData)->base;
  b->xDlError(b, n, msg);
}
void (*xDlSym(sqlite3_vfs* v, void* h, const char* s))(void) {
  sqlite3_vfs* b = static_cast<Shim*>(v->pAppData)->base;
  return b->xDlSym(b, h, s);
}
void xDlClose(sqlite3_vfs* v, void* h) {
  sqlite3_vfs* b = static_cast<Shim*>(v->pAppData)->base;
  b->xDlClose(b, h);
}
int xRandomness(sqlite3_vfs* v, int n, char* out) {
  sqlite3_vfs* b = static_cast<Shim*>(v->pAppData)->base;
  return b->xRandomness(b, n, out);
}
int xSleep(sqlite3_vfs* v, int us) {
  sqlite3_vfs* b = static_cast<Shim*>(v->pAppData)->base;
  return b->xSleep(b, us);
}
int xCurrentTime(sqlite3_vfs* v, double* t) {
  sqlite3_vfs* b = static_cast<Shim*>(v->pAppData)->base;
  return b->xCurrentTime(b, t);
}
int xGetLastError(sqlite3_vfs* v, int n, char* out) {
  sqlite3_vfs* b = static_cast<Shim*>(v->pAppData)->base;
  return b->xGetLastError ? b->xGetLastError(b, n, out) : 0;
}
int xCurrentTimeInt64(sqlite3_vfs* v, sqlite3_int64* t) {
  sqlite3_vfs* b = static_cast<Shim*>(v->pAppData)->base;
  if (b->iVersion >= 2 && b->xCurrentTimeInt64 != nullptr) return b->xCurrentTimeInt64(b, t);
  double d = 0;
  const int rc = b->xCurrentTime(b, &d);
  *t = static_cast<sqlite3_int64>(d * 86400000.0);
  return rc;
}

}  // namespace

sqlite3_vfs* heapShmVfs() {
  static std::mutex mu;
  static std::map<sqlite3_vfs*, Shim*> shims;  // one per underlying VFS, for the process's life
  sqlite3_initialize();
  sqlite3_vfs* base = sqlite3_vfs_find(nullptr);
  std::lock_guard lock(mu);
  Shim*& shim = shims[base];
  if (shim == nullptr) {
    shim = new Shim{};
    shim->base = base;
    shim->name = std::string("foamd-heap-shm-") + base->zName;
    sqlite3_vfs& v = shim->vfs;
    v.iVersion = 2;
    v.szOsFile = static_cast<int>(sizeof(File)) + base->szOsFile;
    v.mxPathname = base->mxPathname;
    v.zName = shim->name.c_str();
    v.pAppData = shim;
    v.xOpen = xOpen;
    v.xDelete = xDelete;
    v.xAccess = xAccess;
    v.xFullPathname = xFullPathname;
    v.xDlOpen = xDlOpen;
    v.xDlError = xDlError;
    v.xDlSym = xDlSym;
    v.xDlClose = xDlClose;
    v.xRandomness = xRandomness;
    v.xSleep = xSleep;
    v.xCurrentTime = xCurrentTime;
    v.xGetLastError = xGetLastError;
    v.xCurrentTimeInt64 = xCurrentTimeInt64;
    sqlite3_vfs_register(&v, 0);
  }
  return &shim->vfs;
}

}  // namespace activefoam::server::sql
