// A sweep's or a tag's jobs with their results, and those jobs grouped by spec values: what
// foam results --sweep/--tag and foam plot --sweep both read.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common.h"

namespace activefoam::client {

// Each job's resolved spec as dotted key → value (scalars only).
std::map<std::string, nlohmann::json> flatSpec(const std::string& spec_json);

// Quantile q of sorted values, linear between order statistics (numpy's and R's default).
double quantile(const std::vector<double>& sorted, double q);

struct Group {
  int jobs = 0, succeeded = 0, failed = 0;            // failed: failed or cancelled
  std::map<std::string, std::vector<double>> values;  // finite values of each result, sorted
};

// Groups the jobs by the values of the spec keys in `by` (dotted, read from each job's resolved
// spec); `rows` (QueryResults) gives the succeeded jobs' results. Sets `err` for a key that a
// job's spec does not have as a number.
std::map<std::vector<double>, Group> aggregateBy(const std::vector<v1::Job>& jobs,
                                                 const v1::QueryResultsResponse& rows,
                                                 const std::vector<std::string>& by,
                                                 std::string& err);

// Every job of a sweep or tag (ListJobs, by pages) and the results of its succeeded jobs
// (QueryResults, only `names` when given). Returns 0, or the exit status of a failed call.
int fetchTable(Conn& conn, const std::string& sweep, const std::string& tag,
               const std::string& outcome, const std::vector<std::string>& names,
               std::vector<v1::Job>& jobs, v1::QueryResultsResponse& resp);

}  // namespace activefoam::client
