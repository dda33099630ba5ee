// foam: the activefoam command-line client (docs/usage.md). Specs go to the server as text
// (TOML/JSON) plus key=value settings, and the server validates them; of the engine only the VTK
// writer is used (foam export).
//
//   foam [--server HOST:PORT] [--token-file F] [--tls-ca F] COMMAND ...
//        (also FOAM_SERVER, FOAM_TOKEN, FOAM_TLS_CA)
//
// Exit codes: 0 success (with --wait / watch: the job succeeded); 1 the job failed or was
// cancelled; 2 usage error or invalid spec (INVALID_ARGUMENT); 3 server unreachable or another
// RPC error; 4 authentication failed (UNAUTHENTICATED); 5 not found.
//
// main declares the global options and dispatches to the subcommand given; each subcommand is
// in commands/ (commands.h), what several of them use in common.h.
#include <cstdlib>
#include <exception>
#include <iostream>
#include <string>
#include <string_view>

#include <CLI/CLI.hpp>

#include "activefoam/host_port.h"
#include "activefoam/pem_file.h"
#include "activefoam/token_file.h"
#include "activefoam/utf8.h"
#include "commands.h"
#include "common.h"

int main(int argc, char** argv) {
  using namespace activefoam::client;
  CLI::App app{"foam: activefoam client (submit, watch, list, show, cancel, results, plot, sweep)"};
  app.footer(
      "exit status: 0 ok (job succeeded for --wait/watch), 1 job failed or cancelled, 2 usage or "
      "invalid spec, 3 server unreachable / RPC error, 4 unauthenticated, 5 not found\n"
      "studies (files of grids and seeds, their reports and verdicts): python3 -m activefoam.study "
      "(docs/usage.md, Studies)");
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("foam ") + ACTIVEFOAM_VERSION);
  Conn conn;
  if (const char* s = std::getenv("FOAM_SERVER"); s && *s) conn.server = s;
  // Set but empty (`FOAM_TOKEN=$TOKEN` with TOKEN unset) is a mistake, not "no auth": the calls
  // would go out without a token and without a word.
  const char* const env_token = std::getenv("FOAM_TOKEN");
  if (env_token) conn.token = env_token;
  std::string token_file, tls_ca_file;
  if (const char* c = std::getenv("FOAM_TLS_CA"); c && *c) tls_ca_file = c;
  app.add_option("--server", conn.server, "server HOST:PORT (env FOAM_SERVER)");
  CLI::Option* const token_opt =
      app.add_option("--token-file", token_file, "file holding the bearer token (env FOAM_TOKEN)");
  CLI::Option* const tls_ca_opt =
      app.add_option("--tls-ca", tls_ca_file,
                     "connect with TLS, trusting the certificate(s) in this PEM file (env "
                     "FOAM_TLS_CA; for foamd --tls-cert, its certificate or its CA)");
  app.set_config("--config", "", "TOML config file (server = ..., token-file = ..., tls-ca = ...)");

  // In the order `foam --help` lists them.
  SubmitOptions submit;
  CLI::App* const submit_cmd = setupSubmit(app, submit);
  WatchOptions watch;
  CLI::App* const watch_cmd = setupWatch(app, watch);
  ListOptions list;
  CLI::App* const list_cmd = setupList(app, list);
  ShowOptions show;
  CLI::App* const show_cmd = setupShow(app, show);
  CancelOptions cancel;
  CLI::App* const cancel_cmd = setupCancel(app, cancel);
  ResultsOptions results;
  CLI::App* const results_cmd = setupResults(app, results);
  PlotOptions plot;
  CLI::App* const plot_cmd = setupPlot(app, plot);
  ExportOptions exportc;
  CLI::App* const export_cmd = setupExport(app, exportc);
  SweepOptions sweep;
  CLI::App* const sweep_cmd = setupSweep(app, sweep);
  ReportArgs report;
  CLI::App* const report_cmd = setupReport(app, report);

  // Every argument may end up in a request (a tag, a setting, an id): non-UTF-8 text (a Latin-1
  // shell, say) would be refused by the server's protobuf parser without a word.
  for (int k = 1; k < argc; ++k)
    if (const std::size_t at = activefoam::invalidUtf8At(argv[k]); at != std::string::npos) {
      const bool value = k > 1 && std::string_view(argv[k - 1]).rfind("--", 0) == 0;
      std::cerr << "foam: argument " << k
                << (value ? " (the value of " + std::string(argv[k - 1]) + ")" : std::string())
                << " is not valid UTF-8 (byte " << at << "); foamd takes UTF-8 text only\n";
      return kUsage;
    }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? kOk : kUsage;
  }
  // Given but empty, as in foamd and the Python client: no token, or no TLS, is never what an
  // empty value meant.
  for (const auto& [opt, value] : {std::pair{token_opt, &token_file}, {tls_ca_opt, &tls_ca_file}})
    if (opt->count() > 0 && value->empty()) {
      std::cerr << "foam: " << opt->get_name()
                << ": empty: name the file, or leave the option out\n";
      return kUsage;
    }
  if (token_file.empty() && env_token)
    if (const std::string bad = activefoam::tokenError(conn.token); !bad.empty()) {
      std::cerr << "foam: FOAM_TOKEN " << bad
                << (conn.token.empty() ? " (set but empty: unset it to connect without a token)"
                                       : "")
                << "\n";
      return kUsage;
    }
  if (const std::string bad = activefoam::hostPortError(conn.server); !bad.empty()) {
    std::cerr << "foam: --server (or FOAM_SERVER): " << bad << "\n";
    return kUsage;
  }
  try {
    if (!tls_ca_file.empty())
      conn.tls_ca =
          activefoam::readPemFile(tls_ca_file, "--tls-ca", activefoam::PemKind::Certificate);
    if (!token_file.empty()) {
      conn.token = activefoam::readTokenFile(token_file);
    }
  } catch (const std::exception& e) {
    std::cerr << "foam: " << e.what() << "\n";
    return kUsage;
  }
  conn.connect();

  if (*report_cmd) return runReport(conn, report);

  try {
    if (*submit_cmd) return runSubmit(conn, submit);
    if (*watch_cmd) return runWatch(conn, watch);
    if (*list_cmd) return runList(conn, list);
    if (*show_cmd) return runShow(conn, show);
    if (*cancel_cmd) return runCancel(conn, cancel);
    if (*results_cmd) return runResults(conn, results);
    if (*export_cmd) return runExport(conn, exportc);
    if (*plot_cmd) return runPlot(conn, plot);
    if (*sweep_cmd) return runSweep(conn, sweep);
  } catch (const std::exception& e) {
    std::cerr << "foam: " << e.what() << "\n";
    return kUsage;
  }
  return kUsage;
}
