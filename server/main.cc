// foamd: the activefoam server (docs/usage.md).
//
//   foamd [--listen HOST:PORT] [--db PATH] [--workers N] [--threads-per-job N]
//         [--token-file F] [--http HOST:PORT [--http-threads N] [--metrics-public]]
//         [--tls-cert F --tls-key F] [--insecure-public] [--config F] [--keep-snapshots N]
//         [--log-level L] [--allow-unstable]
//   foamd --check-db [--db PATH]
//
// With no flags: gRPC on 127.0.0.1:50051, database $XDG_DATA_HOME/activefoam/foamd.db (or
// ~/.local/share/activefoam/foamd.db), one engine worker per core. The config file is TOML with
// the long flag names as keys (listen = "127.0.0.1:50051", workers = 2, ...).
// A non-loopback --listen needs --token-file (and with it TLS) unless --insecure-public; a
// non-loopback --http always needs the token and TLS. The token guards every HTTP route but the
// dashboard's page and /healthz (and /metrics with --metrics-public).
// SIGTERM / SIGINT / SIGHUP / SIGQUIT / SIGXCPU: stop accepting, stop the workers (their jobs go
// back to the queue and resume from their last checkpoint on the next start), close the store,
// with a log line naming the signal. SIGUSR1, SIGUSR2, SIGALRM and the other signals that would
// end a process are logged and ignored; SIGPIPE is ignored (kSignals). Exit 0; 2 on bad usage or
// when the server cannot start.
#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <memory>
#include <sstream>
#include <thread>

#include <openssl/pem.h>
#include <openssl/x509.h>
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include "activefoam/cli_finite.h"
#include "activefoam/host_port.h"
#include "activefoam/pem_file.h"
#include "activefoam/token_file.h"
#include "http.h"
#include "pool.h"
#include "service.h"
#include "slurm.h"
#include "store.h"

namespace fs = std::filesystem;
using namespace activefoam::server;

namespace {

std::string defaultDbPath() {
  fs::path base;
  if (const char* x = std::getenv("XDG_DATA_HOME"); x && *x)
    base = x;
  else if (const char* h = std::getenv("HOME"); h && *h)
    base = fs::path(h) / ".local" / "share";
  else
    base = ".";
  return (base / "activefoam" / "foamd.db").string();
}

// Empty when the key is the certificate's; else what is wrong, naming the options (a mismatched
// pair used to surface as "the port is taken": gRPC's listener failed without saying why).
std::string keyPairError(const std::string& cert_pem, const std::string& key_pem) {
  BIO* cb = BIO_new_mem_buf(cert_pem.data(), static_cast<int>(cert_pem.size()));
  X509* cert = PEM_read_bio_X509(cb, nullptr, nullptr, nullptr);
  BIO_free(cb);
  BIO* kb = BIO_new_mem_buf(key_pem.data(), static_cast<int>(key_pem.size()));
  EVP_PKEY* key = PEM_read_bio_PrivateKey(kb, nullptr, nullptr, nullptr);
  BIO_free(kb);
  std::string why;
  if (!cert)
    why = "--tls-cert: the PEM certificate cannot be parsed";
  else if (!key)
    why = "--tls-key: the PEM private key cannot be parsed";
  else if (X509_check_private_key(cert, key) != 1)
    why = "--tls-cert and --tls-key do not belong together: the key is not the certificate's";
  X509_free(cert);
  EVP_PKEY_free(key);
  return why;
}

std::string utcText(const std::tm& tm) {
  char buf[40];
  std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M:%S UTC", &tm);
  return buf;
}

std::string utcText(const ASN1_TIME* t) {
  std::tm tm{};
  return ASN1_TIME_to_tm(t, &tm) == 1 ? utcText(tm) : "(an unreadable date)";
}

// Empty when every certificate of the PEM file (--tls-cert: the server's, then its chain) is
// valid now; else which one is not, with its dates. An expired certificate was served: clients
// saw only "certificate verify failed" and foamd's log said nothing. One that expires within 30
// days is warned of.
std::string certificateDatesError(const std::string& pem, const std::string& path) {
  BIO* b = BIO_new_mem_buf(pem.data(), static_cast<int>(pem.size()));
  std::time_t now = std::time(nullptr);
  std::tm now_tm{};
  gmtime_r(&now, &now_tm);
  std::string why;
  for (int k = 1; why.empty(); ++k) {
    X509* cert = PEM_read_bio_X509(b, nullptr, nullptr, nullptr);
    if (!cert) break;  // the end (a file without one is keyPairError's to name)
    const ASN1_TIME* from = X509_get0_notBefore(cert);
    const ASN1_TIME* to = X509_get0_notAfter(cert);
    const std::string which = "--tls-cert '" + path + "': " +
                              (k == 1 ? std::string("the certificate")
                                      : "certificate " + std::to_string(k) + " of the file");
    const std::string dates =
        " (valid from " + utcText(from) + " to " + utcText(to) + "; now " + utcText(now_tm) + ")";
    if (X509_cmp_time(from, &now) > 0)
      why = which + " is not valid yet" + dates +
            ": check this machine's clock, or use a certificate valid now";
    else if (X509_cmp_time(to, &now) < 0)
      why = which + " has expired" + dates + ": renew it";
    else if (std::time_t soon = now + 30 * 86400; X509_cmp_time(to, &soon) < 0)
      spdlog::warn("foamd: {} expires on {}: renew it before then (clients will refuse it)", which,
                   utcText(to));
    X509_free(cert);
  }
  BIO_free(b);
  return why;
}

// "INI was not able to parse token_file" → the key, what it is, and the closest known key.
std::string configErrorMessage(const CLI::App& app, const std::string& what) {
  const std::string prefix = "INI was not able to parse ";
  if (what.rfind(prefix, 0) != 0) return what;
  const std::string key = what.substr(prefix.size());
  std::string best;
  std::size_t best_d = std::string::npos;
  for (const CLI::Option* o : app.get_options()) {
    for (const std::string& name : o->get_lnames()) {
      if (name == "config" || name == "help" || name == "version") continue;
      const std::size_t d = activefoam::editDistance(key, name);
      if (d < best_d) best_d = d, best = name;
    }
  }
  std::string msg = "unknown key '" + key + "'";
  if (best_d <= std::max<std::size_t>(2, key.size() / 3)) msg += " (did you mean '" + best + "'?)";
  return msg + "; the keys are the long flag names without '--'";
}

// The signals foamd takes in its main thread (sigwait): those that stop it, and those that are
// logged and ignored. Between them, every standard asynchronous signal whose default action ends
// a process, but SIGPIPE and SIGXFSZ (ignored outright, main) and SIGPROF (left to a profiler).
struct SignalAction {
  int sig;
  const char* name;
  bool stops;
};
constexpr SignalAction kSignals[] = {
    {SIGTERM, "SIGTERM", true},     {SIGINT, "SIGINT", true},
    {SIGHUP, "SIGHUP", true},    // the terminal closed
    {SIGQUIT, "SIGQUIT", true},  // its default would dump core: a stop here, with the store closed
    {SIGXCPU, "SIGXCPU", true},  // the soft CPU limit: stop cleanly before the hard one kills
    {SIGUSR1, "SIGUSR1", false},    {SIGUSR2, "SIGUSR2", false},
    {SIGALRM, "SIGALRM", false},    {SIGVTALRM, "SIGVTALRM", false},
    {SIGIO, "SIGIO", false},        {SIGPWR, "SIGPWR", false},
    {SIGSTKFLT, "SIGSTKFLT", false}};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"foamd: activefoam simulation server (gRPC API, SQLite store, engine pool)"};
  std::string listen = "127.0.0.1:50051", db = defaultDbPath(), token_file, http, cert, key;
  std::string log_level = "info", spheroid_cache;
  int workers = 0, threads_per_job = 0, keep_snapshots = 0;
  double checkpoint_every_s = 60;
  app.add_option("--listen", listen, "gRPC address HOST:PORT")->capture_default_str();
  app.add_option("--db", db, "SQLite database file")->capture_default_str();
  app.add_option("--workers", workers, "engine workers (0 = one per core)")
      ->check(CLI::Range(0, 1024));
  app.add_option("--threads-per-job", threads_per_job,
                 "engine threads of each pool job (0 = max(1, cores / workers)); results are "
                 "bit-identical for any count")
      ->check(CLI::Range(0, 1024));
  CLI::Option* const token_opt =
      app.add_option("--token-file", token_file, "file holding the bearer token every call needs");
  app.add_option("--http", http,
                 "HTTP endpoint HOST:PORT: the dashboard at /, read-only JSON, /metrics, "
                 "/healthz");
  bool metrics_public = false, insecure_public = false;
  int http_threads = HttpOptions{}.threads;
  app.add_option(
         "--http-threads", http_threads,
         "HTTP worker threads (they answer whole requests: headers are read by one epoll thread)")
      ->check(CLI::Range(4, 1024))
      ->capture_default_str();
  app.add_flag("--metrics-public", metrics_public,
               "serve /metrics without the token (for Prometheus scrapers); the other routes "
               "keep it");
  app.add_flag("--insecure-public", insecure_public,
               "allow a non-loopback --listen without --token-file (a trusted network only: "
               "anyone who reaches it can submit and cancel jobs)");
  bool allow_unstable = false;
  app.add_flag("--allow-unstable", allow_unstable,
               "accept jobs whose time step lies beyond the measured stable range "
               "(docs/study/stability-map.md; refused by default): for measuring where a method "
               "fails, e.g. a new contact setting at a larger step");
  app.add_option("--tls-cert", cert, "TLS certificate (PEM)");
  app.add_option("--tls-key", key, "TLS private key (PEM)");
  app.add_option("--keep-snapshots", keep_snapshots,
                 "snapshots kept per job, newest first (0 = all)")
      ->check(CLI::Range(0, 1000000));
  app.add_option("--checkpoint-every-s", checkpoint_every_s,
                 "simulated seconds between checkpoints of a running job")
      ->check(activefoam::finiteNumber())
      ->check(CLI::PositiveNumber);
  app.add_option("--spheroid-cache", spheroid_cache,
                 "directory of prepared spheroids reused by fusion jobs (default: 'spheroids' "
                 "next to the database)");
  std::string executor = "pool";
  SlurmOptions slurm;
  app.add_option("--executor", executor,
                 "where jobs run: pool (engine workers in foamd) or slurm (batch tasks on a "
                 "Slurm cluster; deploy/slurm/README.md)")
      ->check(CLI::IsMember({"pool", "slurm"}))
      ->capture_default_str();
  app.add_option("--slurm-dir", slurm.work_dir,
                 "slurm: work directory on a filesystem shared with the compute nodes (specs, "
                 "checkpoints, outputs; never the database)");
  app.add_option("--slurm-partition", slurm.partition, "slurm: partition (default: the cluster's)");
  app.add_option("--slurm-foam-run", slurm.foam_run,
                 "slurm: foam-run as the compute nodes see it (default: next to foamd)");
  app.add_option("--slurm-foam", slurm.foam,
                 "slurm: the foam client as the compute nodes see it (default: next to foamd)");
  app.add_option("--slurm-report-to", slurm.report_to,
                 "slurm: HOST:PORT the tasks report to (default: --listen)");
  app.add_option("--slurm-token-file", slurm.token_file,
                 "slurm: token file as the compute nodes see it (default: --token-file)");
  app.add_option("--slurm-tls-ca", slurm.tls_ca,
                 "slurm: CA the tasks trust for foamd's TLS certificate (default: --tls-cert)");
  app.add_option("--slurm-sbatch-arg", slurm.sbatch_args,
                 "slurm: extra sbatch argument, e.g. --slurm-sbatch-arg=--time=24:00:00 "
                 "(repeatable)");
  app.add_option("--slurm-checkpoint-every-s", slurm.checkpoint_every_s,
                 "slurm: wall-clock seconds between a task's checkpoints (foam-run "
                 "--checkpoint-every): what a requeued task recomputes at most")
      ->check(activefoam::finiteNumber())
      ->check(CLI::Range(1.0, 1e6))
      ->capture_default_str();
  app.add_option("--slurm-poll-s", slurm.poll_every_s, "slurm: seconds between squeue polls")
      ->check(activefoam::finiteNumber())
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}))
      ->capture_default_str();
  bool check_db = false;
  app.add_flag("--check-db", check_db,
               "check the database (--db) with SQLite's integrity_check, which the start's "
               "quick_check leaves out (every index against its table), print one line and exit: "
               "0 sound, 1 damaged, 2 not checked (no such file, or a foamd serving it)");
  app.set_config("--config", "", "TOML config file (keys = long flag names)");
  // A key the config file misspells must not be dropped: `token_file = ...` for `token-file`
  // started foamd without its token.
  app.allow_config_extras(CLI::config_extras_mode::error);
  app.set_version_flag("--version", std::string("foamd ") + ACTIVEFOAM_VERSION);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ConfigError& e) {
    std::cerr << "foamd: --config: " << configErrorMessage(app, e.what()) << "\n";
    return 2;
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (check_db) {
    try {
      const DbCheck r = checkDatabase(db);
      char cost[96];
      std::snprintf(cost, sizeof cost, "%.1f MiB in %.1f s",
                    static_cast<double>(r.bytes) / (1 << 20), r.seconds);
      if (r.ok) {
        std::cout << "foamd --check-db: database '" << db << "' is sound (integrity_check: ok; "
                  << cost << ")" << std::endl;
        return 0;
      }
      std::cout << "foamd --check-db: database '" << db
                << "' is damaged (integrity_check: " << r.problems.substr(0, 600) << "; " << cost
                << "): restore it from a backup, or move it aside with its -wal and -shm files"
                << std::endl;
      return 1;
    } catch (const std::exception& e) {
      std::cerr << "foamd --check-db: " << e.what() << "\n";
      return 2;
    }
  }
  // Given but empty (`--token-file ''`, `token-file = ""` in the config) once started foamd
  // without auth and without a word.
  if (token_opt->count() > 0 && token_file.empty()) {
    std::cerr << "foamd: --token-file: empty: name the file holding the token, or leave the "
                 "option out to run without one\n";
    return 2;
  }
  for (const auto& [flag, value] : {std::pair<const char*, const std::string*>{"--listen", &listen},
                                    {"--http", &http},
                                    {"--slurm-report-to", &slurm.report_to}})
    if (!value->empty())
      if (const std::string bad = activefoam::hostPortError(*value, value != &slurm.report_to);
          !bad.empty()) {
        std::cerr << "foamd: " << flag << ": " << bad << "\n";
        return 2;
      }
  spdlog::set_level(spdlog::level::from_str(log_level));
  spdlog::set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%l%$ %v");

  // Every signal whose default action would end foamd is handled or ignored on purpose (a
  // SIGUSR1 or a SIGALRM once ended it with no log line, the store's writes cut short):
  //   - the stop signals end it cleanly: running jobs re-queued, the store closed, a log line;
  //   - the others that would kill it are logged and ignored;
  //   - SIGPIPE is ignored outright: a client that goes away mid-answer makes that write fail
  //     (EPIPE), not the server end. SIGXFSZ likewise: a write past the file-size limit fails
  //     and the store reports it.
  // The handled ones are blocked in every thread (threads started later inherit the mask) and
  // taken by the main thread's sigwait below.
  signal(SIGPIPE, SIG_IGN);
  signal(SIGXFSZ, SIG_IGN);
  sigset_t sigs;
  sigemptyset(&sigs);
  for (const SignalAction& a : kSignals) sigaddset(&sigs, a.sig);
  pthread_sigmask(SIG_BLOCK, &sigs, nullptr);

  try {
    ServerConfig config;
    config.listen = listen;
    if (!token_file.empty()) {
      config.token = activefoam::readTokenFile(token_file);
    }
    if (!cert.empty())
      config.tls_cert =
          activefoam::readPemFile(cert, "--tls-cert", activefoam::PemKind::Certificate);
    if (const std::string bad = certificateDatesError(config.tls_cert, cert); !bad.empty())
      throw std::runtime_error(bad);
    if (!key.empty())
      config.tls_key = activefoam::readPemFile(key, "--tls-key", activefoam::PemKind::PrivateKey);
    if (!cert.empty() && !key.empty())
      if (const std::string bad = keyPairError(config.tls_cert, config.tls_key); !bad.empty())
        throw std::runtime_error(bad);
    config.insecure_public = insecure_public;
    config.allow_unstable = allow_unstable;
    if (allow_unstable)
      spdlog::warn("foamd: --allow-unstable: specs beyond the measured stable range are accepted");
    HttpOptions http_options;
    http_options.listen = http;
    http_options.token = config.token;
    http_options.tls_cert_path = cert;
    http_options.tls_key_path = key;
    http_options.metrics_public = metrics_public;
    http_options.threads = http_threads;
    // Refused before anything starts: a bad listener must not leave a half-started server.
    checkServerConfig(config);
    if (!http.empty()) checkHttpOptions(http_options);

    if (const fs::path dir = fs::path(db).parent_path(); !dir.empty()) fs::create_directories(dir);
    StoreOptions so;
    so.keep_snapshots = keep_snapshots;
    Store store(db, so);
    spdlog::info("foamd {}: store {} (schema {})", ACTIVEFOAM_VERSION, db, store.schemaVersion());
    // The pool's runs died with the last foamd (they resume from their checkpoints); Slurm
    // tasks outlive it and are reconciled by the executor.
    if (executor == "pool")
      if (const int n =
              store.requeueRunningInBackground("foamd restarted while it was running; re-queued"))
        spdlog::warn("store: {} job(s) were running when foamd stopped; re-queued", n);

    PoolOptions po;
    po.workers = workers;
    po.threads_per_job = threads_per_job;
    po.checkpoint_every_s = checkpoint_every_s;
    po.spheroid_cache_dir = spheroid_cache;
    if (po.spheroid_cache_dir.empty()) {
      const fs::path dir = fs::path(db).parent_path();
      po.spheroid_cache_dir = ((dir.empty() ? fs::path(".") : dir) / "spheroids").string();
    }
    std::unique_ptr<Executor> pool;
    if (executor == "slurm") {
      const fs::path here = fs::read_symlink("/proc/self/exe").parent_path();
      auto sibling = [&](const std::string& given, const char* name, const char* build_dir) {
        if (given != name) return given;
        for (const fs::path& p : {here / name, here / ".." / build_dir / name})
          if (fs::exists(p)) return fs::canonical(p).string();
        return given;
      };
      slurm.foam = sibling(slurm.foam, "foam", "client");
      slurm.foam_run = sibling(slurm.foam_run, "foam-run", "runner");
      if (slurm.report_to.empty()) {
        const std::string host = listen.substr(0, listen.rfind(':'));
        if (host == "0.0.0.0" || host == "[::]" || host == "::")
          throw std::invalid_argument(
              "--listen " + listen +
              " is every address of this machine: give --slurm-report-to HOST:PORT, the "
              "address the compute nodes reach foamd at");
        slurm.report_to = listen;
      }
      if (slurm.token_file.empty() && !token_file.empty())
        slurm.token_file = fs::absolute(token_file).string();
      if (slurm.tls_ca.empty() && !cert.empty()) slurm.tls_ca = fs::absolute(cert).string();
      if (!slurm.work_dir.empty()) slurm.work_dir = fs::absolute(slurm.work_dir).string();
      spdlog::info("foamd: slurm executor: work dir {}, partition {}, tasks report to {}",
                   slurm.work_dir, slurm.partition.empty() ? "(default)" : slurm.partition,
                   slurm.report_to);
      pool = std::make_unique<SlurmExecutor>(store, slurm);
      // A task's report carries one snapshot (zlib SnapshotData): a 2 x 100-cell fusion at 1280
      // triangles is ~4 MiB compressed, beyond gRPC's default 4 MiB.
      config.max_message_bytes = 64 * 1024 * 1024;
    } else {
      pool = std::make_unique<Pool>(store, po);
    }
    FoamServer server(store, *pool, config);
    server.start();
    std::unique_ptr<HttpEndpoint> endpoint;
    if (!http.empty()) endpoint = std::make_unique<HttpEndpoint>(store, *pool, http_options);
    pool->start();

    for (;;) {
      int sig = 0;
      sigwait(&sigs, &sig);
      const SignalAction* a = std::find_if(std::begin(kSignals), std::end(kSignals),
                                           [&](const SignalAction& x) { return x.sig == sig; });
      if (a == std::end(kSignals)) continue;  // not waited for
      if (a->stops) {
        spdlog::info("foamd: {} received, shutting down", a->name);
        break;
      }
      spdlog::warn(
          "foamd: {} received, ignored (foamd stops on SIGTERM, SIGINT, SIGHUP or "
          "SIGQUIT)",
          a->name);
    }
    server.shutdown();
    pool->stop(true);  // pool: running jobs → queued (resume from their checkpoints)
    endpoint.reset();
    store.flush();
    spdlog::info("foamd: stopped");
    return 0;
  } catch (const std::exception& e) {
    spdlog::error("foamd: {}", e.what());
    return 2;
  }
}
