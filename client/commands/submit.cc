// foam submit: one job; its id is the first line on stdout, so a script can read it.
#include <iostream>

#include <CLI/CLI.hpp>

#include "../commands.h"

namespace activefoam::client {

CLI::App* setupSubmit(CLI::App& app, SubmitOptions& o) {
  auto* submit = app.add_subcommand("submit", "submit a job; prints its id on the first line");
  submit->add_option("SPEC", o.spec.file, "spec file (TOML or JSON, docs/model.md §9; - = stdin)");
  submit->add_option("--scene", o.spec.scene,
                     "scene (cell|doublet|spheroid|fusion) instead of a file");
  submit->add_option("--set", o.spec.settings,
                     "override a key: --set cells.alpha=0.5 (repeatable)");
  submit->add_option("--preset", o.spec.preset, kPresetHelp);
  submit->add_option("--accuracy", o.spec.accuracy, kAccuracyHelp);
  submit->add_option("--priority", o.priority, "higher runs first");
  submit->add_option("--tag", o.tag, "free text to filter on");
  submit->add_option("--idempotency-key", o.idempotency_key,
                     "resubmitting with the same key returns the same job");
  submit->add_flag("--wait", o.wait, "follow the job; exit 0 only if it succeeded");
  submit->add_flag("--quiet,-q", o.quiet, "no progress on stderr");
  return submit;
}

int runSubmit(Conn& conn, const SubmitOptions& o) {
  if (o.spec.file.empty() && o.spec.scene.empty()) {
    std::cerr << "foam: submit needs SPEC or --scene\n";
    return kUsage;
  }
  v1::SubmitJobRequest req;
  req.set_spec_text(specText(o.spec.file));
  for (const auto& s : specSettings(o.spec)) req.add_settings(s);
  req.set_priority(o.priority);
  req.set_tag(o.tag);
  req.set_idempotency_key(o.idempotency_key);
  v1::SubmitJobResponse resp;
  auto ctx = conn.ctx();
  const grpc::Status st = conn.stub->SubmitJob(ctx.get(), req, &resp);
  if (!st.ok()) return rpcError(st, "submit");
  std::cout << resp.job_id() << std::endl;
  if (!resp.created()) std::cerr << "foam: already submitted (same idempotency key)\n";
  if (!o.wait) return kOk;
  int rc = kRpc;
  auto final = watch(conn, resp.job_id(), o.quiet, rc);
  return final ? jobExit(*final) : rc;
}

}  // namespace activefoam::client
