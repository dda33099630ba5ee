// The store's SQL: the schema and its migrations, the mapping of rows to messages, and the
// WHERE clauses of the filters that ListJobs, QueryResults and /jobs share.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "activefoam/v1/job.pb.h"
#include "activefoam/v1/service.pb.h"
#include "sqlite.h"

namespace activefoam::server::sql {

// Brings the schema of `db` to kSchemaVersion (store.h) in one transaction; refuses a database
// newer than this foamd.
void migrateSchema(sqlite3* db);

// The columns of `jobs` that make a v1::Job, in readJob's order.
extern const char* kJobCols;
v1::Job readJob(Stmt& s);  // from a row of SELECT kJobCols
std::optional<v1::Job> loadJob(sqlite3* db, const std::string& id);
v1::Job requireJob(sqlite3* db, const std::string& id);  // StoreError NotFound when absent

// A sample's values as a blob (native doubles) and back.
std::string packDoubles(const std::vector<double>& v);
std::vector<double> unpackDoubles(const std::string& s);

// Parameter filter key → column ("cells.alpha" and "alpha" alike).
const std::map<std::string, std::string>& paramColumns();

// WHERE clause and its bound values for the common filters.
struct Where {
  std::string sql = " WHERE 1";
  std::vector<std::variant<std::string, double, std::int64_t>> args;
  void add(const std::string& cond, std::variant<std::string, double, std::int64_t> v) {
    sql += " AND " + cond;
    args.push_back(std::move(v));
  }
  void bindAll(Stmt& s) const {
    int i = 1;
    for (const auto& a : args) std::visit([&](const auto& v) { s.bind(i++, v); }, a);
  }
};

// Adds `outcome = ?` (InvalidArgument naming the field for an unknown outcome).
void addOutcomeFilter(Where& w, const std::string& outcome);
// Adds the ranges (InvalidArgument for an unknown key or a NaN bound).
void addParamFilters(Where& w, const google::protobuf::RepeatedPtrField<v1::ParamRange>& ranges);

}  // namespace activefoam::server::sql
