// A SQLite VFS that forwards to the default one and fails writes on demand (SQLITE_FULL, as a
// full disk does): fault injection for the store without a tmpfs or root. Installed as the
// default VFS of the test process, so the store opens its database through it unchanged.
#pragma once

#include <sqlite3.h>

#include <atomic>

namespace faulty_vfs {

inline std::atomic<bool> fail_writes{false};

namespace detail {

inline sqlite3_vfs* real = nullptr;

struct File {
  sqlite3_file base;
  sqlite3_file* real;  // the real VFS's file, allocated right after this struct
};

inline sqlite3_file* inner(sqlite3_file* f) {
  return reinterpret_cast<File*>(f)->real;
}

inline int xClose(sqlite3_file* f) {
  return inner(f)->pMethods->xClose(inner(f));
}
inline int xRead(sqlite3_file* f, void* p, int n, sqlite3_int64 off) {
  return inner(f)->pMethods->xRead(inner(f), p, n, off);
}
inline int xWrite(sqlite3_file* f, const void* p, int n, sqlite3_int64 off) {
  if (fail_writes.load()) return SQLITE_FULL;
  return inner(f)->pMethods->xWrite(inner(f), p, n, off);
}
inline int xTruncate(sqlite3_file* f, sqlite3_int64 size) {
  return inner(f)->pMethods->xTruncate(inner(f), size);
}
inline int xSync(sqlite3_file* f, int flags) {
  if (fail_writes.load()) return SQLITE_IOERR_FSYNC;
  return inner(f)->pMethods->xSync(inner(f), flags);
}
inline int xFileSize(sqlite3_file* f, sqlite3_int64* size) {
  return inner(f)->pMethods->xFileSize(inner(f), size);
}
inline int xLock(sqlite3_file* f, int l) {
  return inner(f)->pMethods->xLock(inner(f), l);
}
inline int xUnlock(sqlite3_file* f, int l) {
  return inner(f)->pMethods->xUnlock(inner(f), l);
}
inline int xCheckReservedLock(sqlite3_file* f, int* out) {
  return inner(f)->pMethods->xCheckReservedLock(inner(f), out);
}
inline int xFileControl(sqlite3_file* f, int op, void* arg) {
  return inner(f)->pMethods->xFileControl(inner(f), op, arg);
}
inline int xSectorSize(sqlite3_file* f) {
  return inner(f)->pMethods->xSectorSize(inner(f));
}
inline int xDeviceCharacteristics(sqlite3_file* f) {
  return inner(f)->pMethods->xDeviceCharacteristics(inner(f));
}
inline int xShmMap(sqlite3_file* f, int pg, int sz, int extend, void volatile** p) {
  return inner(f)->pMethods->xShmMap(inner(f), pg, sz, extend, p);
}
inline int xShmLock(sqlite3_file* f, int offset, int n, int flags) {
  return inner(f)->pMethods->xShmLock(inner(f), offset, n, flags);
}
inline void xShmBarrier(sqlite3_file* f) {
  inner(f)->pMethods->xShmBarrier(inner(f));
}
inline int xShmUnmap(sqlite3_file* f, int del) {
  return inner(f)->pMethods->xShmUnmap(inner(f), del);
}
// No memory-mapped reads: every read goes through xRead (iVersion 2).

inline const sqlite3_io_methods methods = {2,
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

inline int xOpen(sqlite3_vfs*, const char* name, sqlite3_file* f, int flags, int* out) {
  auto* ff = reinterpret_cast<File*>(f);
  ff->real = reinterpret_cast<sqlite3_file*>(ff + 1);
  const int rc = real->xOpen(real, name, ff->real, flags, out);
  f->pMethods = ff->real->pMethods ? &methods : nullptr;
  return rc;
}
inline int xDelete(sqlite3_vfs*, const char* name, int sync) {
  return real->xDelete(real, name, sync);
}
inline int xAccess(sqlite3_vfs*, const char* name, int flags, int* out) {
  return real->xAccess(real, name, flags, out);
}
inline int xFullPathname(sqlite3_vfs*, const char* name, int n, char* out) {
  return real->xFullPathname(real, name, n, out);
}

inline sqlite3_vfs vfs{};

}  // namespace detail

// Makes the wrapper the default VFS (once per process).
inline void install() {
  using namespace detail;
  if (real) return;
  real = sqlite3_vfs_find(nullptr);
  vfs = *real;
  vfs.zName = "faulty";
  vfs.szOsFile = static_cast<int>(sizeof(File)) + real->szOsFile;
  vfs.pNext = nullptr;
  vfs.xOpen = xOpen;
  vfs.xDelete = xDelete;
  vfs.xAccess = xAccess;
  vfs.xFullPathname = xFullPathname;
  sqlite3_vfs_register(&vfs, 1);
}

}  // namespace faulty_vfs
