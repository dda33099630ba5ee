// What several foam subcommands use (see common.h).
#include "common.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <thread>

#include <google/protobuf/util/json_util.h>

#include "activefoam/utf8.h"

namespace activefoam::client {
namespace {

// A spec beyond this is a mistake (a data file given as the spec), refused before it is sent.
constexpr std::uintmax_t kMaxSpecBytes = 1 << 20;

std::string fmtDuration(double s) {
  char b[64];
  if (s < 0)
    return "?";
  else if (s < 60)
    std::snprintf(b, sizeof b, "%.1fs", s);
  else if (s < 3600)
    std::snprintf(b, sizeof b, "%dm%02ds", static_cast<int>(s / 60), static_cast<int>(s) % 60);
  else
    std::snprintf(b, sizeof b, "%dh%02dm", static_cast<int>(s / 3600),
                  static_cast<int>(s / 60) % 60);
  return b;
}

}  // namespace

bool Conn::loopback() const {
  const std::string host = server.substr(0, server.rfind(':'));
  return host == "localhost" || host == "[::1]" || host.rfind("127.", 0) == 0;
}

void Conn::connect() {
  // With a token and no TLS the server wants local credentials (loopback): see foamd
  // --token-file.
  std::shared_ptr<grpc::ChannelCredentials> creds;
  if (!tls_ca.empty()) {
    grpc::SslCredentialsOptions o;
    o.pem_root_certs = tls_ca;
    creds = grpc::SslCredentials(o);
  } else if (!token.empty() && loopback()) {
    creds = grpc::experimental::LocalCredentials(LOCAL_TCP);
  } else {
    creds = grpc::InsecureChannelCredentials();
  }
  stub = v1::Foam::NewStub(grpc::CreateChannel(server, creds));
}

std::unique_ptr<grpc::ClientContext> Conn::ctx(double deadline_s) const {
  auto c = std::make_unique<grpc::ClientContext>();
  if (!token.empty()) c->AddMetadata("authorization", "Bearer " + token);
  if (deadline_s > 0)
    c->set_deadline(std::chrono::system_clock::now() +
                    std::chrono::milliseconds(static_cast<long>(deadline_s * 1000)));
  return c;
}

int rpcError(const grpc::Status& s, const std::string& what) {
  std::cerr << "foam: " << what << ": " << s.error_message() << " (" << s.error_code() << ")\n";
  switch (s.error_code()) {
    case grpc::StatusCode::INVALID_ARGUMENT:
    case grpc::StatusCode::FAILED_PRECONDITION:
    case grpc::StatusCode::RESOURCE_EXHAUSTED:  // a request beyond the server's size limit
      return kUsage;
    case grpc::StatusCode::UNAUTHENTICATED:
      return kAuth;
    case grpc::StatusCode::NOT_FOUND:
      return kNotFound;
    default:
      return kRpc;
  }
}

std::string stateName(v1::JobState s) {
  std::string n = v1::JobState_Name(s);
  n = n.substr(std::string("JOB_STATE_").size());
  for (char& c : n) c = static_cast<char>(std::tolower(c));
  return n;
}

namespace {

// At most kMaxSpecBytes from a stream, whatever it is: /dev/zero and `yes |` have no size to
// check first (foam submit /dev/zero was OOM-killed at 24 GB without the cap).
std::string readCapped(std::istream& in, const std::string& name) {
  std::string out(kMaxSpecBytes + 1, '\0');
  in.read(out.data(), static_cast<std::streamsize>(out.size()));
  out.resize(static_cast<std::size_t>(in.gcount()));
  if (out.size() > kMaxSpecBytes)
    throw std::runtime_error(name +
                             " holds more than 1 MiB; a spec or certificate file has at "
                             "most 1 MiB");
  return out;
}

}  // namespace

std::string readFile(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw std::runtime_error("'" + path + "' is a directory, not a file");
  if (const auto size = std::filesystem::file_size(path, ec); !ec && size > kMaxSpecBytes)
    throw std::runtime_error("'" + path + "' has " + std::to_string(size) +
                             " bytes; a spec or certificate file has at most 1 MiB");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read '" + path + "'");
  return readCapped(in, "'" + path + "'");
}

std::string toJsonText(const google::protobuf::Message& m) {
  std::string s;
  google::protobuf::util::JsonPrintOptions o;
  o.preserve_proto_field_names = true;
  (void)google::protobuf::util::MessageToJsonString(m, &s, o);
  return s;
}

std::optional<v1::Job> watch(Conn& conn, const std::string& id, bool quiet, int& rc) {
  std::int64_t last = 0;
  std::vector<std::string> columns;
  std::string latest;                    // latest observable, "name = value"
  std::int64_t rejected_in_samples = 0;  // Σ of the samples' steps_rejected (Slurm tasks' too)
  std::optional<v1::Job> final;
  int failures = 0;
  const bool tty = isatty(2);
  for (;;) {
    v1::WatchJobRequest req;
    req.set_job_id(id);
    req.set_from_seq(last);
    req.set_follow(true);
    auto ctx = conn.ctx(0);
    auto reader = conn.stub->WatchJob(ctx.get(), req);
    v1::JobEvent ev;
    while (reader->Read(&ev)) {
      failures = 0;
      last = ev.seq();
      if (ev.has_state()) {
        if (!quiet)
          std::cerr << (tty ? "\r\033[K" : "") << "foam: " << id << " "
                    << stateName(ev.state().state())
                    << (ev.state().reason().empty() ? "" : ": " + ev.state().reason()) << "\n";
        if (activefoam::v1::JobState s = ev.state().state(); s == v1::JOB_STATE_SUCCEEDED ||
                                                             s == v1::JOB_STATE_FAILED ||
                                                             s == v1::JOB_STATE_CANCELLED)
          final = ev.state();
      } else if (ev.has_sample()) {
        if (ev.columns_size() > 0) columns.assign(ev.columns().begin(), ev.columns().end());
        const auto& v = ev.sample().values();
        // The scene's first observable follows the columns every scene has (run.h).
        constexpr int kCommonColumns = 7;
        if (v.size() > kCommonColumns && static_cast<int>(columns.size()) > kCommonColumns) {
          char b[128];
          std::snprintf(b, sizeof b, "%s = %.4g", columns[kCommonColumns].c_str(),
                        v[kCommonColumns]);
          latest = b;
        }
        for (int k = 0; k < v.size() && k < static_cast<int>(columns.size()); ++k)
          if (columns[static_cast<std::size_t>(k)] == "steps_rejected" && std::isfinite(v[k]))
            rejected_in_samples += static_cast<std::int64_t>(v[k]);
      } else if (ev.has_progress() && !quiet) {
        const auto& p = ev.progress();
        const int width = 30;
        const int filled = static_cast<int>(std::lround(p.fraction() * width));
        std::string bar(static_cast<std::size_t>(filled), '#');
        bar.resize(width, '.');
        char b[256];
        const std::int64_t rejected = std::max(p.steps_rejected(), rejected_in_samples);
        char rej[48] = "";
        if (rejected > 0)
          std::snprintf(rej, sizeof rej, "  rejected %lld", static_cast<long long>(rejected));
        std::snprintf(b, sizeof b, "[%s] %5.1f%%  t = %.4g s  ETA %s%s  %s", bar.c_str(),
                      100 * p.fraction(), p.t_s(), fmtDuration(p.eta_s()).c_str(), rej,
                      latest.c_str());
        std::cerr << (tty ? "\r\033[K" : "") << b << (tty ? "" : "\n") << std::flush;
      }
    }
    const grpc::Status st = reader->Finish();
    if (final) return final;
    if (st.ok()) {  // stream ended without a terminal state (server going down): follow again
    } else if (st.error_code() != grpc::StatusCode::UNAVAILABLE &&
               st.error_code() != grpc::StatusCode::CANCELLED) {
      rc = rpcError(st, "watch " + id);
      return std::nullopt;
    }
    if (++failures > 600) {
      rc = rpcError(st, "watch " + id + " (gave up reconnecting)");
      return std::nullopt;
    }
    if (!quiet && failures == 1)
      std::cerr << "\nfoam: connection lost; reconnecting and resuming after event " << last
                << "\n";
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
}

int jobExit(const v1::Job& j) {
  return j.state() == v1::JOB_STATE_SUCCEEDED ? kOk : kJobNotOk;
}

std::string specText(const std::string& spec_file) {
  if (spec_file.empty()) return "";
  std::string text;
  if (spec_file == "-") {
    text = readCapped(std::cin, "standard input");
  } else {
    text = readFile(spec_file);
  }
  if (const std::size_t at = activefoam::invalidUtf8At(text); at != std::string::npos) {
    const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<long>(at), '\n');
    throw std::runtime_error("'" + spec_file + "': not valid UTF-8 at byte " + std::to_string(at) +
                             " (line " + std::to_string(line) + "); save the spec as UTF-8");
  }
  return text;
}

std::vector<std::string> specSettings(const SpecOptions& o) {
  std::vector<std::string> settings = o.settings;
  // --preset and --accuracy are settings like --set ones (the spec's order does not matter).
  if (!o.preset.empty()) settings.insert(settings.begin(), "numerics.preset=" + o.preset);
  for (const auto& a : o.accuracy) settings.insert(settings.begin(), "accuracy." + a);
  if (!o.scene.empty()) settings.insert(settings.begin(), "scene=" + o.scene);
  return settings;
}

}  // namespace activefoam::client
