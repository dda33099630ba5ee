// foam sweep: a grid of jobs over spec keys and seeds, submitted as one sweep.
#include <algorithm>
#include <iostream>
#include <sstream>

#include <CLI/CLI.hpp>

#include "../commands.h"

namespace activefoam::client {

CLI::App* setupSweep(CLI::App& app, SweepOptions& o) {
  auto* sweep = app.add_subcommand("sweep", "submit a grid sweep; prints the sweep id");
  sweep->add_option("SPEC", o.spec.file, "base spec file");
  sweep->add_option("--scene", o.spec.scene);
  sweep->add_option("--set", o.spec.settings);
  sweep->add_option("--preset", o.spec.preset, kPresetHelp);
  sweep->add_option("--accuracy", o.spec.accuracy, kAccuracyHelp);
  sweep->add_option("--grid", o.grid, "key=v1,v2,... (repeatable; cartesian product)");
  sweep->add_option("--seeds", o.seeds, "seeds (each parameter set runs once per seed)")
      ->delimiter(',');
  sweep->add_option("--tag", o.tag);
  sweep->add_flag("--wait", o.wait, "follow every job; exit 0 only if all succeeded");
  return sweep;
}

int runSweep(Conn& conn, const SweepOptions& o) {
  v1::SubmitSweepRequest req;
  req.set_spec_text(specText(o.spec.file));
  for (const auto& s : specSettings(o.spec)) req.add_settings(s);
  for (const auto& g : o.grid) {
    const auto eq = g.find('=');
    if (eq == std::string::npos) {
      std::cerr << "foam: --grid wants key=v1,v2,...\n";
      return kUsage;
    }
    auto* axis = req.add_grid();
    axis->set_key(g.substr(0, eq));
    std::stringstream vs(g.substr(eq + 1));
    for (std::string v; std::getline(vs, v, ',');) axis->add_values(v);
  }
  for (auto s : o.seeds) req.add_seeds(s);
  req.set_tag(o.tag);
  v1::SubmitSweepResponse resp;
  auto ctx = conn.ctx();
  const grpc::Status st = conn.stub->SubmitSweep(ctx.get(), req, &resp);
  if (!st.ok()) return rpcError(st, "sweep");
  std::cout << resp.sweep_id() << std::endl;
  std::cerr << "foam: " << resp.job_ids_size() << " jobs\n";
  if (!o.wait) return kOk;
  int worst = kOk;
  for (const auto& jid : resp.job_ids()) {
    int rc = kRpc;
    auto final = watch(conn, jid, true, rc);
    const int e = final ? jobExit(*final) : rc;
    if (final) std::cerr << "foam: " << jid << " " << stateName(final->state()) << "\n";
    worst = std::max(worst, e);
  }
  return worst;
}

}  // namespace activefoam::client
