// The foam subcommands, one file each in commands/. A command's options struct is what CLI11
// fills while parsing, so it outlives the parse in main; setupX declares the subcommand and its
// options on the app and returns it (main asks it whether it was given); runX performs the
// command on a connected Conn and returns the exit code.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "activefoam/vtk.h"
#include "common.h"
#include "report.h"

namespace CLI {
class App;
}

namespace activefoam::client {

struct SubmitOptions {
  SpecOptions spec;
  int priority = 0;
  std::string tag;
  std::string idempotency_key;
  bool wait = false;
  bool quiet = false;
};
CLI::App* setupSubmit(CLI::App& app, SubmitOptions& o);
int runSubmit(Conn& conn, const SubmitOptions& o);

struct WatchOptions {
  std::string id;
  bool quiet = false;
};
CLI::App* setupWatch(CLI::App& app, WatchOptions& o);
int runWatch(Conn& conn, const WatchOptions& o);

struct ListOptions {
  std::vector<std::string> states;
  std::string tag;
  std::string sweep;
  std::string outcome;
  int limit = 50;
  bool json = false;
};
CLI::App* setupList(CLI::App& app, ListOptions& o);
int runList(Conn& conn, const ListOptions& o);

struct ShowOptions {
  std::string id;
  bool json = false;
};
CLI::App* setupShow(CLI::App& app, ShowOptions& o);
int runShow(Conn& conn, const ShowOptions& o);

struct CancelOptions {
  std::string id;
};
CLI::App* setupCancel(CLI::App& app, CancelOptions& o);
int runCancel(Conn& conn, const CancelOptions& o);

// One job's results (an ID), or a table of a sweep's or tag's jobs (no ID).
struct ResultsOptions {
  std::string id;
  std::string sweep;
  std::string tag;
  std::string outcome;
  std::vector<std::string> metrics;
  std::vector<std::string> by;
  bool json = false;
  bool csv = false;
};
CLI::App* setupResults(CLI::App& app, ResultsOptions& o);
int runResults(Conn& conn, const ResultsOptions& o);

// One job's samples over time (an ID), or a sweep's results (--sweep).
struct PlotOptions {
  std::string id;
  std::string out;  // empty: a name made of the job or sweep and what is plotted
  std::string column = "theta_deg";
  std::string sweep;
  std::string x;
  std::string y;
  std::string by;
  std::vector<std::string> heatmap;
};
CLI::App* setupPlot(CLI::App& app, PlotOptions& o);
int runPlot(Conn& conn, const PlotOptions& o);

struct ExportOptions {
  std::string id;
  std::string dir;  // empty: job-ID
  // --movie: FILE (.mp4 or .gif) rendered from the snapshots instead of the VTK files.
  bool movie = false;
  std::string movie_file;
  double fps = 4;
  std::string size = "1280x720";
  std::string color = "spheroid";
};
CLI::App* setupExport(CLI::App& app, ExportOptions& o);
int runExport(Conn& conn, const ExportOptions& o);
int runMovie(Conn& conn, const ExportOptions& o);  // export --movie (commands/movie.cc)

// Snapshot `info` of a job, fetched (GetSnapshot) and decoded; an error text, empty on success.
std::string fetchSnapshot(v1::Foam::Stub& stub,
                          const std::function<std::unique_ptr<grpc::ClientContext>()>& newCtx,
                          const std::string& job_id, const v1::SnapshotInfo& info, VtkMesh& mesh);

struct SweepOptions {
  SpecOptions spec;
  std::vector<std::string> grid;
  std::vector<std::uint64_t> seeds;
  std::string tag;
  bool wait = false;
};
CLI::App* setupSweep(CLI::App& app, SweepOptions& o);
int runSweep(Conn& conn, const SweepOptions& o);

// The work is reportTask (report.h).
CLI::App* setupReport(CLI::App& app, ReportArgs& o);
int runReport(Conn& conn, const ReportArgs& o);

}  // namespace activefoam::client
