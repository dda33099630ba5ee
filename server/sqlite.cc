// SQLite helpers (see sqlite.h).
#include "sqlite.h"

#include "heap_shm_vfs.h"

namespace activefoam::server::sql {

// Failures of the storage, not of the statement: the same write may succeed later.
bool storageFailure(int code) {
  switch (code) {
    case SQLITE_FULL:
    case SQLITE_IOERR:
    case SQLITE_READONLY:
    case SQLITE_CANTOPEN:
    case SQLITE_NOMEM:
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
    case SQLITE_PROTOCOL:
      return true;
    default:
      return false;
  }
}

bool storageFailure(const std::exception_ptr& e) {
  try {
    std::rethrow_exception(e);
  } catch (const SqliteError& s) {
    return storageFailure(s.code);
  } catch (...) {
    return false;
  }
}

void check(int rc, sqlite3* db, const char* what) {
  if (rc != SQLITE_OK && rc != SQLITE_DONE && rc != SQLITE_ROW)
    throw SqliteError(rc, std::string(what) + ": " + sqlite3_errmsg(db));
}

void exec(sqlite3* db, const std::string& sql) {
  char* err = nullptr;
  if (const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err); rc != SQLITE_OK) {
    std::string msg = err ? err : "?";
    sqlite3_free(err);
    throw SqliteError(rc, "sqlite: " + msg + " in: " + sql.substr(0, 80));
  }
}

sqlite3* openDb(const std::string& path, int busy_ms) {
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(path.c_str(), &db,
                      SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX,
                      heapShmVfs()->zName) != SQLITE_OK) {
    std::string msg = db ? sqlite3_errmsg(db) : "out of memory";
    sqlite3_close(db);
    throw std::runtime_error("cannot open database '" + path + "': " + msg);
  }
  sqlite3_busy_timeout(db, busy_ms);
  exec(db, "PRAGMA journal_mode=WAL; PRAGMA synchronous=FULL; PRAGMA foreign_keys=ON;");
  return db;
}

}  // namespace activefoam::server::sql
