// Read-only HTTP endpoint (see http.h).
#include "http.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cctype>
#include <cmath>
#include <cstring>
#include <sstream>
#include <stdexcept>
#include <vector>

#include <google/protobuf/util/json_util.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

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

HttpEndpoint::HttpEndpoint(Store& store, Executor& pool, const std::string& listen)
    : store_(store), pool_(pool) {
  const auto colon = listen.rfind(':');
  if (colon == std::string::npos) throw std::runtime_error("--http: expected HOST:PORT");
  std::string host = listen.substr(0, colon);
  const std::string port = listen.substr(colon + 1);
  if (host.size() > 1 && host.front() == '[') host = host.substr(1, host.size() - 2);
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE;
  addrinfo* res = nullptr;
  if (getaddrinfo(host.c_str(), port.c_str(), &hints, &res) != 0 || !res)
    throw std::runtime_error("--http: cannot resolve " + listen);
  fd_ = socket(res->ai_family, SOCK_STREAM, 0);
  int one = 1;
  setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  if (fd_ < 0 || bind(fd_, res->ai_addr, res->ai_addrlen) != 0 || ::listen(fd_, 16) != 0) {
    freeaddrinfo(res);
    if (fd_ >= 0) close(fd_);
    throw std::runtime_error("--http: cannot listen on " + listen + ": " + std::strerror(errno));
  }
  freeaddrinfo(res);
  sockaddr_storage ss{};
  socklen_t len = sizeof ss;
  getsockname(fd_, reinterpret_cast<sockaddr*>(&ss), &len);
  port_ = ntohs(ss.ss_family == AF_INET6 ? reinterpret_cast<sockaddr_in6*>(&ss)->sin6_port
                                         : reinterpret_cast<sockaddr_in*>(&ss)->sin_port);
  thread_ = std::thread([this] { loop(); });
  spdlog::info("foamd: HTTP (read-only JSON, /metrics) on {} (port {})", listen, port_);
}

HttpEndpoint::~HttpEndpoint() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  if (fd_ >= 0) close(fd_);
}

std::string HttpEndpoint::handle(const std::string& target, int& code, std::string& type) {
  code = 200;
  type = "application/json";
  try {
    std::vector<std::pair<std::string, std::string>> query;
    const std::string path = splitQuery(target, query);
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

void HttpEndpoint::loop() {
  while (!stop_) {
    pollfd p{fd_, POLLIN, 0};
    if (poll(&p, 1, 200) <= 0) continue;
    const int c = accept(fd_, nullptr, nullptr);
    if (c < 0) continue;
    timeval tv{2, 0};
    setsockopt(c, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    std::string req;
    char buf[2048];
    while (req.find("\r\n\r\n") == std::string::npos && req.size() < 16384) {
      const ssize_t n = recv(c, buf, sizeof buf, 0);
      if (n <= 0) break;
      req.append(buf, static_cast<std::size_t>(n));
    }
    int code = 400;
    std::string type = "text/plain", body = "bad request\n";
    std::istringstream line(req.substr(0, req.find("\r\n")));
    std::string method, path;
    line >> method >> path;
    if (method == "GET")
      body = handle(path, code, type);
    else if (!method.empty()) {
      code = 405;
      body = "read-only endpoint: GET only\n";
    }
    const char* text = code == 200   ? "OK"
                       : code == 404 ? "Not Found"
                       : code == 405 ? "Method Not Allowed"
                       : code == 500 ? "Internal Server Error"
                       : code == 503 ? "Service Unavailable"
                                     : "Bad Request";
    std::string resp = "HTTP/1.0 " + std::to_string(code) + " " + text +
                       "\r\nContent-Type: " + type +
                       "\r\nContent-Length: " + std::to_string(body.size()) +
                       "\r\nConnection: close\r\n\r\n" + body;
    std::size_t off = 0;
    while (off < resp.size()) {
      const ssize_t n = send(c, resp.data() + off, resp.size() - off, MSG_NOSIGNAL);
      if (n <= 0) break;
      off += static_cast<std::size_t>(n);
    }
    close(c);
  }
}

}  // namespace activefoam::server
