// foam cancel: asks foamd to cancel a queued or running job.
#include <iostream>

#include <CLI/CLI.hpp>

#include "../commands.h"

namespace activefoam::client {

CLI::App* setupCancel(CLI::App& app, CancelOptions& o) {
  auto* cancel = app.add_subcommand("cancel", "cancel a queued or running job");
  cancel->add_option("ID", o.id)->required();
  return cancel;
}

int runCancel(Conn& conn, const CancelOptions& o) {
  v1::CancelJobRequest req;
  req.set_job_id(o.id);
  req.set_reason("cancelled with foam cancel");
  v1::Job j;
  auto ctx = conn.ctx();
  const grpc::Status st = conn.stub->CancelJob(ctx.get(), req, &j);
  if (!st.ok()) return rpcError(st, "cancel " + o.id);
  // A running job stops at its next step: the answer is the request, not the state yet.
  std::cout << (j.state() == v1::JOB_STATE_RUNNING ? std::string("cancelling")
                                                   : stateName(j.state()))
            << "\n";
  return kOk;
}

}  // namespace activefoam::client
