// foam export: a job's snapshots as files that ParaView opens.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>

#include <CLI/CLI.hpp>

#include "../commands.h"
#include "activefoam/cli_finite.h"
#include "activefoam/snapshot_vtk.h"
#include "activefoam/vtk.h"

namespace activefoam::client {

std::string fetchSnapshot(v1::Foam::Stub& stub,
                          const std::function<std::unique_ptr<grpc::ClientContext>()>& newCtx,
                          const std::string& job_id, const v1::SnapshotInfo& info,
                          activefoam::VtkMesh& mesh) {
  v1::GetSnapshotRequest req;
  req.set_job_id(job_id);
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
  return activefoam::decodeSnapshot(info, compression, std::move(data), mesh);
}

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
    activefoam::VtkMesh snap;
    if (std::string err = fetchSnapshot(stub, newCtx, r.job().id(), info, snap); !err.empty())
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
      "export",
      "write a job's snapshots as VTK PolyData (.vtp) + series.pvd for ParaView, or with "
      "--movie as a video (ffmpeg)");
  exportc->add_option("ID", o.id)->required();
  exportc->add_option("FILE", o.movie_file, "with --movie: the video to write (.mp4 or .gif)");
  exportc->add_option("--out,-o", o.dir, "folder (default: job-ID)");
  exportc->add_flag("--movie", o.movie,
                    "render the snapshots to FILE (.mp4 or .gif) with ffmpeg: one frame a "
                    "snapshot, a fixed camera on both spheroids, the time in a corner");
  exportc->add_option("--fps", o.fps, "with --movie: frames (snapshots) a second")
      ->capture_default_str()
      ->check(activefoam::finiteNumber())
      ->check(CLI::Range(0.1, 120.0));
  exportc->add_option("--size", o.size, "with --movie: WIDTHxHEIGHT in pixels")
      ->capture_default_str();
  exportc
      ->add_option("--color", o.color,
                   "with --movie: spheroid | cell | pressure | volume (as the dashboard)")
      ->capture_default_str();
  return exportc;
}

int runExport(Conn& conn, const ExportOptions& o) {
  if (o.movie) return runMovie(conn, o);
  if (!o.movie_file.empty()) {
    std::cerr << "foam: export " << o.id << ": FILE " << o.movie_file
              << " is for --movie (the VTK files go to --out DIR)\n";
    return kUsage;
  }
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
