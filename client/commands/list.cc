// foam list: one page of jobs, newest first.
#include <cctype>
#include <cstdio>
#include <iostream>

#include <CLI/CLI.hpp>

#include "../commands.h"

namespace activefoam::client {

CLI::App* setupList(CLI::App& app, ListOptions& o) {
  auto* list = app.add_subcommand("list", "list jobs, newest first");
  list->add_option("--state", o.states, "queued|running|succeeded|failed|cancelled");
  list->add_option("--tag", o.tag);
  list->add_option("--sweep", o.sweep);
  list->add_option("--outcome", o.outcome, kOutcomeHelp);
  list->add_option("--limit", o.limit, "page size")->check(CLI::Range(1, 1000));
  list->add_flag("--json", o.json);
  return list;
}

int runList(Conn& conn, const ListOptions& o) {
  v1::ListJobsRequest req;
  for (const auto& s : o.states) {
    v1::JobState st;
    std::string u = "JOB_STATE_";
    for (char c : s) u += static_cast<char>(std::toupper(c));
    if (!v1::JobState_Parse(u, &st)) {
      std::cerr << "foam: --state: unknown state '" << s << "'\n";
      return kUsage;
    }
    req.add_states(st);
  }
  req.set_tag(o.tag);
  req.set_sweep_id(o.sweep);
  req.set_outcome(o.outcome);
  req.set_page_size(o.limit);
  v1::ListJobsResponse resp;
  auto ctx = conn.ctx();
  const grpc::Status st = conn.stub->ListJobs(ctx.get(), req, &resp);
  if (!st.ok()) return rpcError(st, "list");
  if (o.json) {
    std::cout << toJsonText(resp) << "\n";
    return kOk;
  }
  std::printf("%-16s %-10s %-8s %-10s %6s %7s %-24s %s\n", "ID", "STATE", "SCENE", "OUTCOME",
              "SEED", "PROG", "CREATED", "TAG");
  for (const auto& j : resp.jobs())
    std::printf("%-16s %-10s %-8s %-10s %6llu %6.1f%% %-24s %s\n", j.id().c_str(),
                stateName(j.state()).c_str(), j.scene().c_str(),
                j.outcome().empty() ? "-" : j.outcome().c_str(),
                static_cast<unsigned long long>(j.seed()), 100 * j.progress(),
                j.created_utc().c_str(), j.tag().c_str());
  if (resp.total() > resp.jobs_size())
    std::cerr << "foam: " << resp.jobs_size() << " of " << resp.total() << " jobs shown\n";
  return kOk;
}

}  // namespace activefoam::client
