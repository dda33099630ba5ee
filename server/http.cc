// foamd's HTTP side (see http.h).
#include "http.h"

#include <cctype>
#include <chrono>
#include <cmath>
#include <cstring>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <vector>

#include <google/protobuf/util/json_util.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "activefoam/run_output.h"
#include "activefoam/snapshot_vtk.h"
#include "activefoam/vtk.h"
#include "dashboard_assets.h"
#include "http_front.h"
#include "listen.h"
#include "mesh_frame.h"

#include <openssl/err.h>
#include <openssl/ssl.h>

// Last: it pulls in <resolv.h>, whose `_res` macro breaks Eigen parameter names.
#include <httplib.h>

namespace activefoam::server {
namespace {

nlohmann::json toJson(const google::protobuf::Message& m) {
  std::string s;
  google::protobuf::util::JsonPrintOptions o;
  o.preserve_proto_field_names = true;
  o.always_print_primitive_fields = true;
  (void)google::protobuf::util::MessageToJsonString(m, &s, o);
  return nlohmann::json::parse(s);
}

std::string urlDecode(const std::string& in) {
  std::string out;
  for (std::size_t k = 0; k < in.size(); ++k) {
    if (in[k] == '+') {
      out += ' ';
    } else if (in[k] == '%' && k + 2 < in.size() &&
               std::isxdigit(static_cast<unsigned char>(in[k + 1])) &&
               std::isxdigit(static_cast<unsigned char>(in[k + 2]))) {
      out += static_cast<char>(std::stoi(in.substr(k + 1, 2), nullptr, 16));
      k += 2;
    } else {
      out += in[k];
    }
  }
  return out;
}

std::vector<std::string> splitList(const std::string& v) {
  std::vector<std::string> out;
  std::stringstream ss(v);
  for (std::string item; std::getline(ss, item, ',');)
    if (!item.empty()) out.push_back(item);
  return out;
}

StoreError badQuery(const std::string& name, const std::string& why) {
  return StoreError(StoreError::Kind::InvalidArgument, "query parameter '" + name + "': " + why);
}

double number(const std::string& name, const std::string& v) {
  char* end = nullptr;
  const double x = std::strtod(v.c_str(), &end);
  if (v.empty() || *end != '\0' || !std::isfinite(x))
    throw badQuery(name, "'" + v + "' is not a finite number");
  return x;
}

std::int32_t count(const std::string& name, const std::string& v, std::int32_t max) {
  const double x = number(name, v);
  if (x < 1 || x > max || x != std::floor(x))
    throw badQuery(name, "'" + v + "' is not an integer in [1, " + std::to_string(max) + "]");
  return static_cast<std::int32_t>(x);
}

// `param.KEY=MIN:MAX` (either side may be empty) → a parameter range filter.
void addRange(const std::string& name, const std::string& v,
              google::protobuf::RepeatedPtrField<v1::ParamRange>* out) {
  const auto colon = v.find(':');
  v1::ParamRange r;
  r.set_key(name.substr(6));
  if (r.key().empty()) throw badQuery(name, "no parameter key after 'param.'");
  const std::string lo = colon == std::string::npos ? v : v.substr(0, colon);
  const std::string hi = colon == std::string::npos ? v : v.substr(colon + 1);
  if (!lo.empty()) r.set_min(number(name, lo));
  if (!hi.empty()) r.set_max(number(name, hi));
  *out->Add() = r;
}

// The filters /jobs and /results share (ListJobs and QueryResults have the same fields for
// them); false when `name` is not one of them.
template <class Request>
bool commonFilter(const std::string& name, const std::string& v, Request& req) {
  if (name == "scene")
    req.set_scene(v);
  else if (name == "tag")
    req.set_tag(v);
  else if (name == "sweep")
    req.set_sweep_id(v);
  else if (name == "outcome")
    req.set_outcome(v);
  else if (name.rfind("param.", 0) == 0)
    addRange(name, v, req.mutable_params());
  else
    return false;
  return true;
}

// Splits "/path?a=1&b=2" into the path and decoded (name, value) pairs.
std::string splitQuery(const std::string& target,
                       std::vector<std::pair<std::string, std::string>>& query) {
  const auto q = target.find('?');
  if (q == std::string::npos) return target;
  std::stringstream ss(target.substr(q + 1));
  for (std::string item; std::getline(ss, item, '&');) {
    if (item.empty()) continue;
    const auto eq = item.find('=');
    query.emplace_back(urlDecode(item.substr(0, eq)),
                       eq == std::string::npos ? "" : urlDecode(item.substr(eq + 1)));
  }
  return target.substr(0, q);
}

}  // namespace

void checkHttpOptions(const HttpOptions& o) {
  const auto colon = o.listen.rfind(':');
  if (colon == std::string::npos || colon + 1 == o.listen.size())
    throw std::invalid_argument("--http '" + o.listen + "': expected HOST:PORT");
  if (o.tls_cert_path.empty() != o.tls_key_path.empty())
    throw std::invalid_argument("--http with TLS needs both --tls-cert and --tls-key");
  if (!isLoopback(o.listen) && (o.token.empty() || o.tls_cert_path.empty()))
    throw std::invalid_argument(
        "--http " + o.listen +
        " is not a loopback address: it needs --token-file and --tls-cert/--tls-key (jobs, "
        "specs and results would otherwise be readable by anyone who reaches it; for a local "
        "dashboard use 127.0.0.1)");
  if (o.threads < 4 || o.threads > 1024)
    throw std::invalid_argument("--http-threads " + std::to_string(o.threads) +
                                ": allowed range [4, 1024]");
  if (o.header_timeout_s < 1 || o.read_timeout_s < 1 || o.max_connections_per_client < 1 ||
      o.max_connections < o.max_connections_per_client)
    throw std::invalid_argument("HTTP limits out of range (timeouts >= 1 s, connections >= 1)");
}

namespace {

// A Host header naming this machine's loopback interface: localhost, 127.a.b.c, [::1] (with or
// without a port). Without a token, only such requests are served: a page on another site that
// rebinds its DNS name to 127.0.0.1 reaches the port, but sends its own name.
bool loopbackHostHeader(std::string host) {
  if (!host.empty() && host.front() == '[') {
    host = host.substr(0, host.find(']') == std::string::npos ? host.size() : host.find(']') + 1);
  } else if (const auto colon = host.rfind(':'); colon != std::string::npos) {
    host.resize(colon);
  }
  for (char& ch : host) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  if (host == "localhost" || host == "[::1]") return true;
  static const std::regex ipv4_loopback(R"(127\.\d{1,3}\.\d{1,3}\.\d{1,3})");
  return std::regex_match(host, ipv4_loopback);
}

// What a browser or a probe may fetch without the token: the page (no data in it), health.
bool isPublic(const std::string& path, bool metrics_public) {
  if (path == "/healthz") return true;
  if (path == "/metrics") return metrics_public;
  return findDashboardAsset(path) != nullptr;
}

// Compares in time independent of where the first difference is.
bool sameSecret(const std::string& a, const std::string& b) {
  unsigned diff = a.size() == b.size() ? 0u : 1u;
  for (std::size_t k = 0; k < a.size(); ++k)
    diff |= static_cast<unsigned char>(a[k]) ^ static_cast<unsigned char>(k < b.size() ? b[k] : 0);
  return diff == 0;
}

// Every answer is whole: a Range header is ignored (RFC 7233 allows it) and the answer says so.
// cpp-httplib cut any answer's body to the range asked, whatever its status, and left the status
// as the handler set it: `Range: bytes=0-9` got "200" with 10 bytes of JSON, and a 401 was cut
// to `{"error":"`. The answers are built per request (a job's JSON changes as it runs) and carry
// no validator a client could resume against, so a part of one is not served.
void ignoreRanges(const httplib::Request& req, httplib::Response& res) {
  // The library parsed the ranges into this request, which it owns and does not hold const.
  const_cast<httplib::Request&>(req).ranges.clear();
  if (!res.has_header("Accept-Ranges")) res.set_header("Accept-Ranges", "none");
}

void jsonError(httplib::Response& res, int code, const std::string& what) {
  res.status = code;
  res.set_content(nlohmann::json{{"error", what}}.dump(), "application/json");
}

}  // namespace

namespace {

// The library's request parsing and routing, fed a connection by HttpFront.
class Router : public httplib::Server {
 public:
  void serveOne(httplib::Stream& strm) {
    bool closed = true;
    // One request per connection (the answer says `Connection: close`): a refusal on a
    // kept-alive one (a GET's unread body, a POST without a length) left the client waiting
    // out the keep-alive, and an unread body was parsed as the next request. A read-only
    // endpoint polled every few seconds loses nothing by it.
    (void)process_request(strm, true, closed, nullptr);
  }
};

std::string sslError() {
  char buf[256] = "";
  ERR_error_string_n(ERR_get_error(), buf, sizeof buf);
  return buf;
}

}  // namespace

HttpEndpoint::HttpEndpoint(Store& store, Executor& pool, HttpOptions options)
    : store_(store), pool_(pool), options_(std::move(options)) {
  checkHttpOptions(options_);
  const bool tls = !options_.tls_cert_path.empty();
  std::unique_ptr<SSL_CTX, void (*)(SSL_CTX*)> ctx(nullptr, SSL_CTX_free);
  if (tls) {
    ctx.reset(SSL_CTX_new(TLS_server_method()));
    SSL_CTX* c = ctx.get();
    if (c == nullptr || SSL_CTX_set_min_proto_version(c, TLS1_2_VERSION) != 1 ||
        SSL_CTX_use_certificate_chain_file(c, options_.tls_cert_path.c_str()) != 1 ||
        SSL_CTX_use_PrivateKey_file(c, options_.tls_key_path.c_str(), SSL_FILETYPE_PEM) != 1 ||
        SSL_CTX_check_private_key(c) != 1)
      throw std::runtime_error("--http: cannot use the TLS certificate '" + options_.tls_cert_path +
                               "' with the key '" + options_.tls_key_path + "': " + sslError());
    SSL_CTX_set_options(c, SSL_OP_NO_COMPRESSION | SSL_OP_NO_RENEGOTIATION);
    SSL_CTX_set_mode(c, SSL_MODE_ENABLE_PARTIAL_WRITE | SSL_MODE_ACCEPT_MOVING_WRITE_BUFFER);
  }
  http_ = std::make_unique<Router>();
  httplib::Server& srv = *http_;
  srv.set_payload_max_length(64 * 1024);  // GET only: a body is never needed

  // A refusal before any route (true: `res` holds it): the method, a body, the target's length,
  // the Host without a token, the token.
  auto refused = [this](const httplib::Request& req, httplib::Response& res) {
    // Before the library reads any body (it waits up to the read timeout for one without a
    // length): every write is gRPC's.
    if (req.method != "GET" && req.method != "HEAD") {
      res.set_header("Allow", "GET, HEAD");
      jsonError(res, 405, "read-only endpoint: GET only (submit and cancel through gRPC: foam)");
      return true;
    }
    // The library does not read a GET's body at all: a request that has one is refused.
    if (req.has_header("Transfer-Encoding") ||
        (req.has_header("Content-Length") && req.get_header_value("Content-Length") != "0")) {
      jsonError(res, 413, "a " + req.method + " request takes no body");
      return true;
    }
    if (req.target.size() > options_.max_target_bytes) {
      jsonError(res, 414,
                "request target of " + std::to_string(req.target.size()) + " bytes; the limit is " +
                    std::to_string(options_.max_target_bytes));
      return true;
    }
    if (options_.token.empty() && req.has_header("Host") &&
        !loopbackHostHeader(req.get_header_value("Host"))) {
      jsonError(res, 403,
                "Host '" + req.get_header_value("Host").substr(0, 200) +
                    "' is not a loopback name: without --token-file foamd answers only requests "
                    "addressed to localhost, 127.0.0.0/8 or [::1] (a page elsewhere could reach "
                    "it by rebinding its DNS name)");
      return true;
    }
    if (!options_.token.empty() && !isPublic(req.path, options_.metrics_public) &&
        !sameSecret(req.get_header_value("Authorization"), "Bearer " + options_.token)) {
      res.set_header("WWW-Authenticate", "Bearer realm=\"foamd\"");
      jsonError(res, 401,
                req.has_header("Authorization") ? "wrong token"
                                                : "missing 'Authorization: Bearer <token>'");
      return true;
    }
    return false;
  };
  auto answer = [this](const httplib::Request& req, httplib::Response& res) {
    int code = 200;
    std::string type;
    std::string body = handle(req.target, code, type);
    res.status = code;
    res.set_content(std::move(body), type);
  };
  srv.set_pre_routing_handler([refused](const httplib::Request& req, httplib::Response& res) {
    ignoreRanges(req, res);
    return refused(req, res) ? httplib::Server::HandlerResponse::Handled
                             : httplib::Server::HandlerResponse::Unhandled;
  });
  srv.Get(".*", answer);
  srv.set_error_handler([refused, answer](const httplib::Request& req, httplib::Response& res) {
    ignoreRanges(req, res);
    // The library answers a Range header it cannot parse (another unit, FIRST > LAST) with 416
    // before any route; it is ignored here as every Range is: the whole answer.
    if (res.status == 416 && res.body.empty()) {
      if (!refused(req, res)) answer(req, res);
      return;
    }
    // The library's own refusals (a malformed request, a target too long) come without a body.
    if (!res.body.empty()) return;
    const int c = res.status;
    const char* what = c == 400   ? "malformed request"
                       : c == 404 ? "not found"
                       : c == 413 ? "request body too large (GET only)"
                       : c == 414 ? "request target too long"
                       : c == 431 ? "request headers too large"
                                  : "error";
    res.set_content(nlohmann::json{{"error", what}}.dump(), "application/json");
  });

  const auto colon = options_.listen.rfind(':');
  std::string host = options_.listen.substr(0, colon);
  if (host.size() > 1 && host.front() == '[') host = host.substr(1, host.size() - 2);
  int port = 0;
  try {
    port = std::stoi(options_.listen.substr(colon + 1));
  } catch (const std::exception&) {
    port = -1;
  }
  if (port < 0 || port > 65535)
    throw std::invalid_argument("--http '" + options_.listen + "': port out of [0, 65535]");
  // cpp-httplib 0.11 set SO_REUSEPORT on its listener: a second foamd on a taken port bound
  // too and the kernel split the requests between the two. bindHttpListener sets
  // SO_REUSEADDR only, so a taken port fails here.
  if (const std::string why = loopbackSiblingTaken(options_.listen); !why.empty())
    throw std::runtime_error("--http: cannot listen on " + options_.listen + ": " + why);
  const int fd = bindHttpListener(host, port);
  if (fd < 0)
    throw std::runtime_error("--http: cannot listen on " + options_.listen +
                             ": the port is taken or the address is not this machine's");
  port_ = port;
  FrontOptions front;
  front.workers = options_.threads;
  front.header_timeout_s = options_.header_timeout_s;
  front.io_timeout_s = options_.read_timeout_s;
  front.max_per_client = options_.max_connections_per_client;
  front.max_connections = options_.max_connections;
  front_ = std::make_unique<HttpFront>(fd, ctx.get(), front, [this](httplib::Stream& strm) {
    static_cast<Router&>(*http_).serveOne(strm);
  });
  tls_ = ctx.release();
  spdlog::info("foamd: HTTP (dashboard at /, JSON, /metrics) on {} (port {}){}{}{}",
               options_.listen, port_, tls ? ", TLS" : "",
               options_.token.empty() ? "" : ", token required",
               options_.token.empty() || !options_.metrics_public ? "" : " (not for /metrics)");
}

HttpEndpoint::~HttpEndpoint() {
  front_.reset();  // its workers answer through http_ and tls_
  SSL_CTX_free(tls_);
}
std::string HttpEndpoint::handle(const std::string& target, int& code, std::string& type) {
  code = 200;
  type = "application/json";
  try {
    std::vector<std::pair<std::string, std::string>> query;
    const std::string path = splitQuery(target, query);
    if (const DashboardAsset* asset = findDashboardAsset(path)) {
      type = asset->content_type;
      return std::string(asset->body);
    }
    if (path == "/metrics") {
      type = "text/plain; version=0.0.4";
      const auto counts = store_.countByState();
      auto count = [&](v1::JobState s) {
        auto it = counts.find(s);
        return it == counts.end() ? 0 : it->second;
      };
      const PoolStats& st = pool_.stats();
      std::ostringstream o;
      o << "# HELP foamd_queue_depth Jobs waiting to run.\n# TYPE foamd_queue_depth gauge\n"
        << "foamd_queue_depth " << count(v1::JOB_STATE_QUEUED) << "\n"
        << "# HELP foamd_running_jobs Jobs running now.\n# TYPE foamd_running_jobs gauge\n"
        << "foamd_running_jobs " << st.running.load() << "\n"
        << "# HELP foamd_workers Engine workers.\n# TYPE foamd_workers gauge\n"
        << "foamd_workers " << pool_.workers() << "\n"
        << "# HELP foamd_steps_total Engine steps taken by this process (rate() = steps/s).\n"
        << "# TYPE foamd_steps_total counter\nfoamd_steps_total " << st.steps_total.load() << "\n"
        << "# HELP foamd_jobs_finished_total Jobs finished by this process, by outcome.\n"
        << "# TYPE foamd_jobs_finished_total counter\n"
        << "foamd_jobs_finished_total{state=\"succeeded\"} " << st.jobs_succeeded.load() << "\n"
        << "foamd_jobs_finished_total{state=\"failed\"} " << st.jobs_failed.load() << "\n"
        << "foamd_jobs_finished_total{state=\"cancelled\"} " << st.jobs_cancelled.load() << "\n"
        << "# HELP foamd_store_errors_total Failed tries to write the store (disk full, I/O).\n"
        << "# TYPE foamd_store_errors_total counter\nfoamd_store_errors_total "
        << store_.storeErrors() << "\n"
        << "# HELP foamd_store_degraded 1 while store writes fail.\n"
        << "# TYPE foamd_store_degraded gauge\nfoamd_store_degraded " << (store_.degraded() ? 1 : 0)
        << "\n"
        << "# HELP foamd_jobs Jobs in the store by state.\n# TYPE foamd_jobs gauge\n";
      for (auto s : {v1::JOB_STATE_QUEUED, v1::JOB_STATE_RUNNING, v1::JOB_STATE_SUCCEEDED,
                     v1::JOB_STATE_FAILED, v1::JOB_STATE_CANCELLED})
        o << "foamd_jobs{state=\"" << v1::JobState_Name(s) << "\"} " << count(s) << "\n";
      return o.str();
    }
    if (path == "/healthz") {
      if (!store_.degraded()) return "{\"status\":\"ok\"}";
      code = 503;  // writes failing: a probe must see it
      return nlohmann::json{{"status", "degraded"}, {"store_error", store_.lastError()}}.dump();
    }
    if (path == "/jobs") {
      // The filters of ListJobs: state (comma-separated), tag, sweep, scene, outcome,
      // param.KEY=MIN:MAX, page_size (default 1000), page_token.
      v1::ListJobsRequest req;
      req.set_page_size(1000);
      for (const auto& [name, v] : query) {
        if (commonFilter(name, v, req)) continue;
        if (name == "state") {
          for (const std::string& st : splitList(v)) {
            std::string upper = "JOB_STATE_";
            for (char c : st)
              upper += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
            v1::JobState js;
            if (!v1::JobState_Parse(upper, &js) || js == v1::JOB_STATE_UNSPECIFIED)
              throw badQuery(name, "'" + st +
                                       "' is not one of queued, running, succeeded, failed, "
                                       "cancelled");
            req.add_states(js);
          }
        } else if (name == "page_size") {
          req.set_page_size(count(name, v, 1000));
        } else if (name == "page_token") {
          req.set_page_token(v);
        } else {
          throw badQuery(name,
                         "unknown (known: state, tag, sweep, scene, outcome, "
                         "param.KEY=MIN:MAX, page_size, page_token)");
        }
      }
      return toJson(store_.listJobs(req)).dump();
    }
    if (path == "/results") {
      // QueryResults: scene, tag, sweep, outcome, param.KEY=MIN:MAX, names (comma-separated),
      // limit.
      v1::QueryResultsRequest req;
      for (const auto& [name, v] : query) {
        if (commonFilter(name, v, req)) continue;
        if (name == "names") {
          for (const std::string& n : splitList(v)) req.add_names(n);
        } else if (name == "limit") {
          req.set_limit(count(name, v, 100000));
        } else {
          throw badQuery(name,
                         "unknown (known: scene, tag, sweep, outcome, param.KEY=MIN:MAX, "
                         "names, limit)");
        }
      }
      return toJson(store_.queryResults(req)).dump();
    }
    if (!query.empty() && path.rfind("/jobs/", 0) == 0)
      throw badQuery(query.front().first, "a job's pages take no query parameters");
    if (path.rfind("/jobs/", 0) == 0) {
      std::string rest = path.substr(6);
      std::string what;
      if (auto slash = rest.find('/'); slash != std::string::npos) {
        what = rest.substr(slash + 1);
        rest = rest.substr(0, slash);
      }
      if (what.empty()) {
        auto j = store_.getJob(rest);
        if (!j) throw StoreError(StoreError::Kind::NotFound, "no job " + cappedQuote(rest));
        return toJson(*j).dump();
      }
      if (what == "results") return toJson(store_.results(rest, false)).dump();
      if (what == "samples.csv") {
        const v1::JobResults r = store_.results(rest, true);
        type = "text/csv";
        std::string csv = csvLine(std::vector<std::string>(r.columns().begin(), r.columns().end()));
        csv += '\n';
        for (const auto& smp : r.samples())
          csv += csvLine(std::vector<double>(smp.values().begin(), smp.values().end())) + '\n';
        return csv;
      }
      // snapshots/N.vtp or snapshots/N.mesh (N = an index of the job's results, or latest)
      const bool vtp = what.size() > 14 && what.compare(what.size() - 4, 4, ".vtp") == 0;
      const bool binary = what.size() > 15 && what.compare(what.size() - 5, 5, ".mesh") == 0;
      if (what.rfind("snapshots/", 0) == 0 && (vtp || binary)) {
        const std::string which = what.substr(10, what.size() - 10 - (vtp ? 4 : 5));
        int index = -1;
        if (which != "latest") {
          if (which.empty() || which.size() > 9 ||
              which.find_first_not_of("0123456789") != std::string::npos)
            throw badQuery("snapshot",
                           cappedQuote(which) + " is neither 'latest' nor a snapshot index");
          index = std::stoi(which);
        }
        if (!store_.getJob(rest))
          throw StoreError(StoreError::Kind::NotFound, "no job " + cappedQuote(rest));
        auto snap = store_.snapshot(rest, index);
        if (!snap)
          throw StoreError(StoreError::Kind::NotFound,
                           index < 0 ? "the job has no snapshots"
                                     : "the job has no snapshot " + std::to_string(index));
        auto& [info, compression, data] = *snap;
        VtkMesh mesh;
        if (std::string err = decodeSnapshot(info, compression, std::move(data), mesh);
            !err.empty())
          throw std::runtime_error(err);
        if (binary) {
          type = "application/octet-stream";
          return encodeMeshFrame(mesh, info.index());
        }
        std::ostringstream out;
        writeVtp(out, mesh);
        type = "application/xml";
        return out.str();
      }
      if (what == "samples") {
        const v1::JobResults r = store_.results(rest, true);
        nlohmann::json j = {{"columns", r.columns()}, {"rows", nlohmann::json::array()}};
        for (const auto& s : r.samples()) j["rows"].push_back(s.values());
        return j.dump();
      }
    }
    code = 404;
    return "{\"error\":\"not found\"}";
  } catch (const StoreError& e) {
    code = e.kind == StoreError::Kind::NotFound ? 404 : 400;
    return nlohmann::json{{"error", e.what()}}.dump();
  } catch (const std::exception& e) {
    code = 500;
    return nlohmann::json{{"error", e.what()}}.dump();
  }
}

}  // namespace activefoam::server
