// foam show: a job's state on the first line (for scripts), then its details.
#include <exception>
#include <iostream>
#include <sstream>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "../commands.h"

namespace activefoam::client {
namespace {

// "preset standard (contact-implicit-consistent, Δt 1 s, 320 triangles, ε_CG 0.01, contact law
// prisms-overlap), chosen for the accuracy target contact angle ≤ 2°" from a job's record as the
// server's engine reads it (Job.resolved_spec_json: today's keys, whatever version stored it); "?"
// where the server serves none (a record it cannot read, or a server before it served them).
std::string fidelityText(const std::string& resolved_spec_json) {
  try {
    const nlohmann::json spec = nlohmann::json::parse(resolved_spec_json);
    const nlohmann::json& n = spec.at("numerics");
    // A label: null where the record named no preset this engine reads.
    const nlohmann::json& preset = n.at("preset");
    std::ostringstream os;
    os << "preset " << (preset.is_string() ? preset.get<std::string>() : "?") << " ("
       << n.at("integrator").get<std::string>() << ", Δt " << n.at("dt_s").get<double>() << " s, "
       << n.at("triangles_per_cell").get<long long>() << " triangles, ε_CG "
       << n.at("cg_tol").get<double>() << ", contact law " << n.at("contact_law").get<std::string>()
       << ")";
    // Unset targets are null in a resolved spec.
    const nlohmann::json a = spec.value("accuracy", nlohmann::json::object());
    const bool angle = a.contains("contact_angle_deg") && a["contact_angle_deg"].is_number();
    const bool path = a.contains("trajectory_deg") && a["trajectory_deg"].is_number();
    if (angle || path) os << ", chosen for the accuracy target";
    if (angle) os << " contact angle ≤ " << a["contact_angle_deg"].get<double>() << "°";
    if (path) os << " θ(t) RMS ≤ " << a["trajectory_deg"].get<double>() << "°";
    return os.str();
  } catch (const std::exception&) {
    return "?";
  }
}

}  // namespace

CLI::App* setupShow(CLI::App& app, ShowOptions& o) {
  auto* show = app.add_subcommand("show", "print a job's state (first line), then its details");
  show->add_option("ID", o.id)->required();
  show->add_flag("--json", o.json);
  return show;
}

int runShow(Conn& conn, const ShowOptions& o) {
  v1::GetJobRequest req;
  req.set_job_id(o.id);
  v1::Job j;
  auto ctx = conn.ctx();
  const grpc::Status st = conn.stub->GetJob(ctx.get(), req, &j);
  if (!st.ok()) return rpcError(st, "show " + o.id);
  if (o.json) {
    std::cout << toJsonText(j) << "\n";
    return kOk;
  }
  std::cout << stateName(j.state()) << "\n"
            << "id:        " << j.id() << "\n"
            << "scene:     " << j.scene() << " (seed " << j.seed() << ")\n"
            << "progress:  " << 100 * j.progress() << " % (t = " << j.t_s() << " s, " << j.steps()
            << " steps)\n"
            << "created:   " << j.created_utc() << "\n"
            << "started:   " << j.started_utc() << "\n"
            << "finished:  " << j.finished_utc() << "\n"
            << "attempts:  " << j.attempts() << "\n"
            << "engine:    " << j.engine_version() << "\n";
  std::cout << "fidelity:  " << fidelityText(j.resolved_spec_json()) << "\n";
  if (!j.executor_ref().empty()) std::cout << "executor:  " << j.executor_ref() << "\n";
  if (!j.outcome().empty()) std::cout << "outcome:   " << j.outcome() << "\n";
  if (!j.reason().empty()) std::cout << "reason:    " << j.reason() << "\n";
  if (!j.tag().empty()) std::cout << "tag:       " << j.tag() << "\n";
  if (!j.sweep_id().empty()) std::cout << "sweep:     " << j.sweep_id() << "\n";
  return kOk;
}

}  // namespace activefoam::client
