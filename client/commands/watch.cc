// foam watch: follows a job to its end; the final state on stdout.
#include <iostream>

#include <CLI/CLI.hpp>

#include "../commands.h"

namespace activefoam::client {

CLI::App* setupWatch(CLI::App& app, WatchOptions& o) {
  auto* watchc = app.add_subcommand("watch", "follow a job: progress, ETA, latest observable");
  watchc->add_option("ID", o.id)->required();
  watchc->add_flag("--quiet,-q", o.quiet);
  return watchc;
}

int runWatch(Conn& conn, const WatchOptions& o) {
  int rc = kRpc;
  auto final = watch(conn, o.id, o.quiet, rc);
  if (!final) return rc;
  std::cout << stateName(final->state()) << "\n";
  return jobExit(*final);
}

}  // namespace activefoam::client
