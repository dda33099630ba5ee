// `foam report`: the reporter of a job that runs outside foamd's own pool (a Slurm task,
// deploy/slurm/). It starts foam-run, watches the run folder foam-run writes (samples.csv,
// snapshots/, summary.json) and sends what foamd does not hold yet with ReportTask; when
// foam-run exits it sends the outcome and exits with foam-run's status. foamd down or unreachable:
// it keeps retrying (backoff up to 30 s) for `give_up_after_s`, so a foamd restart loses nothing.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "activefoam/v1/service.grpc.pb.h"

namespace activefoam::client {

struct ReportArgs {
  std::string job_id;
  std::string run_dir;               // foam-run --out
  std::string attempt;               // the executor's handle of this task ("slurm:123_4")
  std::vector<std::string> command;  // foam-run and its arguments
  double every_s = 1.0;              // how often the folder is read
  double give_up_after_s = 3600;     // foamd unreachable this long: stop trying
};

// Returns foam-run's exit status (or 75 when foamd could not be reached to the end, 1 when
// foamd refused the reports, 127 when foam-run could not start).
int reportTask(v1::Foam::Stub& stub,
               const std::function<std::unique_ptr<grpc::ClientContext>()>& context,
               const ReportArgs& args);

}  // namespace activefoam::client
