// foam export: a job's snapshots as files that ParaView opens.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>

#include <CLI/CLI.hpp>

#include "../commands.h"
#include "activefoam/snapshot_vtk.h"
#include "activefoam/vtk.h"

namespace activefoam::client {
namespace {

namespace fs = std::filesystem;

// Every recorded snapshot of a job as VTK PolyData (DIR/snap_NNNNNN.vtp) and a ParaView time
// series (DIR/series.pvd). Returns an error text, empty on success.
std::string exportSnapshots(v1::Foam::Stub& stub,
                            const std::function<std::unique_ptr<grpc::ClientContext>()>& newCtx,
                            const v1::JobResults& r, const fs::path& dir) {
  if (r.snapshots_size() == 0)
    return "the job has no snapshots (snapshot_every_s = 0, or none recorded yet)";
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return "cannot create " + dir.string() + ": " + ec.message();
  std::vector<std::pair<double, std::string>> series;
  for (const v1::SnapshotInfo& info : r.snapshots()) {
    v1::GetSnapshotRequest req;
    req.set_job_id(r.job().id());
    req.set_index(info.index());
    auto ctx = newCtx();
    auto reader = stub.GetSnapshot(ctx.get(), req);
    v1::SnapshotChunk chunk;
    std::string data, compression;
    bool first = true;
    while (reader->Read(&chunk)) {
      if (first) compression = chunk.compression();
      first = false;
      data += chunk.data();
    }
    if (const grpc::Status st = reader->Finish(); !st.ok())
      return "snapshot " + std::to_string(info.index()) + ": " + st.error_message();
    activefoam::VtkMesh snap;
    if (std::string err = activefoam::decodeSnapshot(info, compression, std::move(data), snap);
        !err.empty())
      return err;
    char name[32];
    std::snprintf(name, sizeof name, "snap_%06d.vtp", info.index());
    std::ofstream out(dir / name);
    try {
      activefoam::writeVtp(out, snap);
    } catch (const std::exception& e) {
      return std::string(name) + ": " + e.what();
    }
    if (!out) return "cannot write " + (dir / name).string();
    series.emplace_back(snap.t_s, name);
  }
  std::ofstream pvd(dir / "series.pvd");
  activefoam::writePvd(pvd, series);
  if (!pvd) return "cannot write " + (dir / "series.pvd").string();
  return "";
}

}  // namespace

CLI::App* setupExport(CLI::App& app, ExportOptions& o) {
  auto* exportc = app.add_subcommand(
      "export", "write a job's snapshots as VTK PolyData (.vtp) + series.pvd for ParaView");
  exportc->add_option("ID", o.id)->required();
  exportc->add_option("--out,-o", o.dir, "folder (default: job-ID)");
  return exportc;
}

int runExport(Conn& conn, const ExportOptions& o) {
  v1::GetResultsRequest req;
  req.set_job_id(o.id);
  v1::JobResults r;
  auto ctx = conn.ctx();
  const grpc::Status st = conn.stub->GetResults(ctx.get(), req, &r);
  if (!st.ok()) return rpcError(st, "export " + o.id);
  const std::string dir = o.dir.empty() ? "job-" + o.id : o.dir;
  if (const std::string err = exportSnapshots(
          *conn.stub, [&] { return conn.ctx(); }, r, dir);
      !err.empty()) {
    std::cerr << "foam: export " << o.id << ": " << err << "\n";
    return kJobNotOk;
  }
  std::cout << (fs::path(dir) / "series.pvd").string() << "\n";
  return kOk;
}

}  // namespace activefoam::client
