// The store's SQLite VFS: the default one, but the WAL index (SQLite's "shared memory") lives in
// this process's heap instead of a memory-mapped `<db>-shm` file. A mapped
// file turns a storage fault into a signal: when the -shm file was made immutable mid-job (or
// its storage turned read-only, or a full tmpfs could not back a page), SQLite's next store into
// the mapping killed foamd with SIGBUS. With the index in the heap every failure of the storage
// is a failed write() that SQLite reports, and the store's retry and degraded mode handle it.
//
// This is sound because one process only uses the database (DbLock, store.h): the connections
// of this process share one index, under the same lock rules SQLite applies between
// connections. Other processes are kept out as SQLite keeps them out of a database in use: the
// VFS holds a write lock (fcntl) on the DMS byte of `<db>-shm`, which every SQLite that opens
// the database in WAL mode must lock first, so `sqlite3 foamd.db` while foamd runs answers
// "database is locked" instead of reading or checkpointing beside an index it cannot see.
// SQLite's memory-mapped I/O of the database file is off too (iVersion 2 methods).
#pragma once

#include <sqlite3.h>

namespace activefoam::server::sql {

// The heap-index VFS over the process's default VFS at the time of the call (a test may
// install its own default first); registered, not made the default.
sqlite3_vfs* heapShmVfs();

}  // namespace activefoam::server::sql
