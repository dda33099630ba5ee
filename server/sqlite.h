// A thin layer over SQLite's C API for the store: errors with their result codes, prepared
// statements with chained binds, and connections opened the way the store needs them.
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <exception>
#include <stdexcept>
#include <string>

namespace activefoam::server::sql {

// An SQLite failure with its primary result code, so that the writer can tell the storage
// failing (disk full, I/O error: retried) from a bad statement (a bug: reported).
struct SqliteError : std::runtime_error {
  int code;
  SqliteError(int c, const std::string& what) : std::runtime_error(what), code(c & 0xff) {}
};

// Failures of the storage, not of the statement: the same write may succeed later (disk full,
// I/O error, read-only, busy).
bool storageFailure(int code);
bool storageFailure(const std::exception_ptr& e);

// Throws SqliteError unless rc is OK, DONE or ROW.
void check(int rc, sqlite3* db, const char* what);
void exec(sqlite3* db, const std::string& sql);

class Stmt {
 public:
  Stmt(sqlite3* db, const std::string& sql) : db_(db) {
    check(sqlite3_prepare_v2(db, sql.c_str(), -1, &st_, nullptr), db, sql.c_str());
  }
  ~Stmt() { sqlite3_finalize(st_); }
  Stmt(const Stmt&) = delete;
  Stmt& operator=(const Stmt&) = delete;

  Stmt& bind(int i, const std::string& v) {
    sqlite3_bind_text(st_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Stmt& bind(int i, const char* v) { return bind(i, std::string(v)); }
  Stmt& bind(int i, double v) {
    sqlite3_bind_double(st_, i, v);
    return *this;
  }
  Stmt& bind(int i, std::int64_t v) {
    sqlite3_bind_int64(st_, i, v);
    return *this;
  }
  Stmt& bind(int i, int v) { return bind(i, static_cast<std::int64_t>(v)); }
  Stmt& blob(int i, const std::string& v) {
    sqlite3_bind_blob(st_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Stmt& null(int i) {
    sqlite3_bind_null(st_, i);
    return *this;
  }
  bool step() {
    const int rc = sqlite3_step(st_);
    check(rc, db_, "step");
    return rc == SQLITE_ROW;
  }
  void run() {
    while (step()) {
    }
  }
  std::int64_t i64(int c) { return sqlite3_column_int64(st_, c); }
  double dbl(int c) { return sqlite3_column_double(st_, c); }
  bool isNull(int c) { return sqlite3_column_type(st_, c) == SQLITE_NULL; }
  std::string text(int c) {
    const auto* p = reinterpret_cast<const char*>(sqlite3_column_blob(st_, c));
    return p ? std::string(p, sqlite3_column_bytes(st_, c)) : std::string();
  }

 private:
  sqlite3* db_;
  sqlite3_stmt* st_ = nullptr;
};

// A connection for the store: read-write, created if missing, WAL, synchronous=FULL, foreign
// keys on, `busy_ms` of busy timeout.
sqlite3* openDb(const std::string& path, int busy_ms);

}  // namespace activefoam::server::sql
