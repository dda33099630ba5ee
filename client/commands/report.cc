// foam report: the command line of reportTask (../report.h), which a Slurm task runs.
#include <CLI/CLI.hpp>

#include "../commands.h"
#include "activefoam/cli_finite.h"

namespace activefoam::client {

CLI::App* setupReport(CLI::App& app, ReportArgs& o) {
  auto* report = app.add_subcommand(
      "report",
      "run foam-run for a job placed outside foamd's pool (a Slurm task) and report its "
      "outputs to foamd; exits with foam-run's status (deploy/slurm/README.md)");
  // Slurm plumbing, not a user's command: left out of `foam --help` (it still has its own).
  report->group("");
  report->add_option("JOB", o.job_id, "job id")->required();
  report->add_option("RUN", o.run_dir, "foam-run's --out folder")->required();
  report->add_option("COMMAND", o.command, "-- foam-run SPEC --out RUN ...")->required();
  report->add_option("--attempt", o.attempt, "the executor's handle of this task")->required();
  report->add_option("--every", o.every_s, "seconds between reads of the folder")
      ->check(activefoam::finiteNumber())
      ->check(CLI::Range(0.05, 3600.0));
  report
      ->add_option("--give-up-after", o.give_up_after_s,
                   "seconds of foamd being unreachable before giving up (exit 75)")
      ->check(activefoam::finiteNumber())
      ->check(CLI::Range(1.0, 1e7));
  return report;
}

int runReport(Conn& conn, const ReportArgs& o) {
  return reportTask(
      *conn.stub, [&] { return conn.ctx(120); }, o);
}

}  // namespace activefoam::client
