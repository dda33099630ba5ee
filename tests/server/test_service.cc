// foamd in-process on a loopback port: the gRPC API end to end (store, pool, service).
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <thread>
#include <variant>

#include "activefoam/run.h"
#include "activefoam/v1/service.grpc.pb.h"
#include "activefoam/vtk.h"
#include "faulty_vfs.h"
#include "http.h"
#include "pool.h"
#include "service.h"
#include "spec_convert.h"
#include "store.h"

using namespace activefoam;
using namespace activefoam::server;
namespace fs = std::filesystem;
using namespace std::chrono_literals;

namespace {

fs::path tempDb() {
  static std::mt19937_64 rng{std::random_device{}()};
  const fs::path dir = fs::temp_directory_path() / ("foamd-test-" + std::to_string(rng()));
  fs::create_directories(dir);
  return dir / "foamd.db";
}

// A tiny cell run: 50 steps with 80 triangles, well under a second.
v1::SubmitJobRequest tinyCell(double duration_s = 5) {
  v1::SubmitJobRequest r;
  auto* s = r.mutable_spec();
  s->mutable_cell();
  s->set_duration_s(duration_s);
  s->set_sample_every_s(1);
  s->set_snapshot_every_s(0);
  s->mutable_numerics()->set_triangles_per_cell(80);
  s->mutable_numerics()->set_dt_s(0.1);  // the step these tests' timings were written at
  return r;
}

std::string readText(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  if (!in) ADD_FAILURE() << "cannot read " << p;
  return ss.str();
}

grpc::ByteBuffer bytes(const std::string& s) {
  grpc::Slice slice(s);
  return grpc::ByteBuffer(&slice, 1);
}

std::string bytes(const grpc::ByteBuffer& b) {
  std::vector<grpc::Slice> slices;
  (void)b.Dump(&slices);
  std::string out;
  for (const auto& s : slices) out.append(reinterpret_cast<const char*>(s.begin()), s.size());
  return out;
}

class ServiceTest : public ::testing::Test {
 protected:
  void startServer(bool start_pool = true, const std::string& token = "", bool tls = false) {
    db_ = tempDb();
    store_ = std::make_unique<Store>(db_.string());
    PoolOptions po;
    po.workers = 2;
    po.progress_every_s = 0.01;
    pool_ = std::make_unique<Pool>(*store_, po);
    ServerConfig config;
    config.listen = "127.0.0.1:0";
    config.token = token;
    if (tls) {
      config.tls_cert = readText(fs::path(SERVER_TEST_DATA) / "test-cert.pem");
      config.tls_key = readText(fs::path(SERVER_TEST_DATA) / "test-key.pem");
    }
    server_ = std::make_unique<FoamServer>(*store_, *pool_, config);
    server_->start();
    if (start_pool) pool_->start();
    addr_ = "127.0.0.1:" + std::to_string(server_->port());
    std::shared_ptr<grpc::ChannelCredentials> creds;
    if (tls) {
      grpc::SslCredentialsOptions o;
      o.pem_root_certs = readText(fs::path(SERVER_TEST_DATA) / "test-cert.pem");
      creds = grpc::SslCredentials(o);
    } else {
      creds = token.empty() ? grpc::InsecureChannelCredentials()
                            : grpc::experimental::LocalCredentials(LOCAL_TCP);
    }
    channel_ = grpc::CreateChannel(addr_, creds);
    stub_ = v1::Foam::NewStub(channel_);
  }
  void TearDown() override {
    if (server_) server_->shutdown();
    if (pool_) pool_->stop(true);
    server_.reset();
    pool_.reset();
    store_.reset();
    if (!db_.empty()) fs::remove_all(db_.parent_path());
  }
  std::unique_ptr<grpc::ClientContext> ctx(const std::string& token = "") {
    auto c = std::make_unique<grpc::ClientContext>();
    c->set_deadline(std::chrono::system_clock::now() + 30s);
    if (!token.empty()) c->AddMetadata("authorization", "Bearer " + token);
    return c;
  }
  std::string submit(const v1::SubmitJobRequest& r) {
    v1::SubmitJobResponse resp;
    auto c = ctx();
    const grpc::Status st = stub_->SubmitJob(c.get(), r, &resp);
    EXPECT_TRUE(st.ok()) << st.error_message();
    return resp.job_id();
  }
  // GetResults of a job, with its samples; an error status fails the test.
  v1::JobResults results(const std::string& id, bool with_samples = true) {
    v1::GetResultsRequest r;
    r.set_job_id(id);
    r.set_with_samples(with_samples);
    v1::JobResults res;
    auto c = ctx();
    EXPECT_TRUE(stub_->GetResults(c.get(), r, &res).ok());
    return res;
  }
  v1::Job get(const std::string& id) {
    v1::GetJobRequest r;
    r.set_job_id(id);
    v1::Job j;
    auto c = ctx();
    EXPECT_TRUE(stub_->GetJob(c.get(), r, &j).ok());
    return j;
  }
  v1::Job waitFor(const std::string& id, bool (*pred)(const v1::Job&), double timeout_s = 60) {
    // Sanitizer builds run the engine several times slower (the asan-server test preset sets
    // FOAM_TEST_TIME_SCALE).
    if (const char* k = std::getenv("FOAM_TEST_TIME_SCALE"))
      timeout_s *= std::max(1.0, std::atof(k));
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    v1::Job j;
    do {
      j = get(id);
      if (pred(j)) return j;
      std::this_thread::sleep_for(5ms);
    } while (std::chrono::steady_clock::now() < end);
    ADD_FAILURE() << "timeout waiting for job " << id << " (state " << j.state() << ")";
    return j;
  }
  // Every event from seq > from, following to the end (or `max` events, then cancel).
  std::vector<v1::JobEvent> watch(const std::string& id, std::int64_t from, int max = -1) {
    v1::WatchJobRequest r;
    r.set_job_id(id);
    r.set_from_seq(from);
    r.set_follow(true);
    grpc::ClientContext c;
    c.set_deadline(std::chrono::system_clock::now() + 60s);
    auto reader = stub_->WatchJob(&c, r);
    std::vector<v1::JobEvent> out;
    v1::JobEvent ev;
    while (reader->Read(&ev)) {
      out.push_back(ev);
      if (max > 0 && static_cast<int>(out.size()) >= max) {
        c.TryCancel();
        break;
      }
    }
    const grpc::Status st = reader->Finish();
    if (max < 0) {
      EXPECT_TRUE(st.ok()) << st.error_message();
    }
    return out;
  }

  fs::path db_;
  std::unique_ptr<Store> store_;
  std::unique_ptr<Pool> pool_;
  std::unique_ptr<FoamServer> server_;
  std::unique_ptr<v1::Foam::Stub> stub_;
  std::shared_ptr<grpc::Channel> channel_;
  std::string addr_;
};

// A key's value in a nested spec document, as JSON (null where it has none).
nlohmann::json jsonAt(const nlohmann::json& doc, std::string key) {
  if (key == "scene") key = "scene.kind";  // the table holds the kind (specToJson)
  const nlohmann::json* node = &doc;
  for (std::size_t begin = 0;;) {
    const std::size_t dot = key.find('.', begin);
    const std::string part = key.substr(begin, dot == std::string::npos ? dot : dot - begin);
    if (!node->is_object() || !node->contains(part)) return nullptr;
    node = &(*node)[part];
    if (dot == std::string::npos) return *node;
    begin = dot + 1;
  }
}

void eraseAt(nlohmann::json& doc, const std::string& key) {
  const std::size_t dot = key.rfind('.');
  nlohmann::json& table = dot == std::string::npos ? doc : doc[key.substr(0, dot)];
  table.erase(key.substr(dot == std::string::npos ? 0 : dot + 1));
}

nlohmann::json asJson(const SpecValue& v) {
  return std::visit([](const auto& x) { return nlohmann::json(x); }, v);
}

// A doublet's record as an earlier version stored it: the contact law named by the two switches
// that preceded numerics.contact_law (here the standard preset's prisms-overlap), and none of the
// keys added since (those with a `before` value in the key table). `rest` is what it ran with
// otherwise: today's resolved spec of the same settings.
struct EarlierRecord {
  SceneSpec spec;
  nlohmann::json rest;  // today's record of the same settings
  nlohmann::json record;
};
EarlierRecord earlierDoublet() {
  const ConvertResult conv = convertSpec(
      v1::SceneSpec{}, "", {"scene=doublet", "cells.alpha=0.6", "numerics.dt_s=0.5", "seed=3"});
  EXPECT_TRUE(conv.ok()) << errorText(conv.errors);
  EarlierRecord e{*conv.spec, specToJson(*conv.spec), {}};
  e.record = e.rest;
  for (const SpecField& f : specFields())
    if (f.before) eraseAt(e.record, f.key);
  e.record["numerics"]["contact_within_prisms"] = true;
  e.record["numerics"]["contact_prisms_overlap_only"] = true;
  return e;
}

bool terminal(const v1::Job& j) {
  return isTerminal(j.state());
}
bool running(const v1::Job& j) {
  return j.state() == v1::JOB_STATE_RUNNING && j.steps() > 0;
}

}  // namespace

TEST_F(ServiceTest, SubmitWatchResults) {
  startServer();
  const std::string id = submit(tinyCell());
  const std::vector<v1::JobEvent> evs = watch(id, 0);
  ASSERT_FALSE(evs.empty());
  int samples = 0;
  for (std::size_t i = 0; i < evs.size(); ++i) {
    EXPECT_EQ(evs[i].seq(), static_cast<std::int64_t>(i + 1));
    samples += evs[i].has_sample();
  }
  EXPECT_EQ(samples, 6);  // t = 0, 1, ..., 5
  ASSERT_TRUE(evs.back().has_state());
  EXPECT_EQ(evs.back().state().state(), v1::JOB_STATE_SUCCEEDED);

  const v1::JobResults res = results(id);
  EXPECT_EQ(res.job().state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(res.samples_size(), 6);
  ASSERT_GE(res.columns_size(), 8);
  EXPECT_EQ(res.columns(5), "dt_min_s");
  EXPECT_EQ(res.columns(6), "steps_rejected");
  EXPECT_EQ(res.columns(7), "aspect_ratio");
  bool has_aspect = false;
  std::optional<double> rejected, dt_min;
  for (const auto& r : res.results()) {
    has_aspect = has_aspect || r.name() == "aspect_ratio";
    if (r.name() == "steps_rejected") rejected = r.value();
    if (r.name() == "dt_min_s") dt_min = r.value();
  }
  EXPECT_TRUE(has_aspect);
  EXPECT_EQ(rejected, 0.0);  // the adaptive time step's totals are results too
  EXPECT_GT(dt_min.value_or(0), 0);
  EXPECT_EQ(res.job().engine_version(), ACTIVEFOAM_VERSION);
}

// A probe asked for in the typed spec: its columns follow the scene's in the job's samples, as
// the engine names them, with no server code of its own.
TEST_F(ServiceTest, ProbeColumnsReachTheJobsSamples) {
  startServer();
  v1::SubmitJobRequest req = tinyCell(3);
  req.mutable_spec()->mutable_observe()->set_dissipation(true);
  const std::string id = submit(req);
  const v1::Job job = waitFor(id, terminal);
  ASSERT_EQ(job.state(), v1::JOB_STATE_SUCCEEDED) << job.reason();
  const v1::JobResults res = results(id);
  SceneSpec spec;
  spec.scene = SceneKind::Cell;
  spec.observe.dissipation = true;
  const std::vector<std::string> want = sampleColumns(spec);
  ASSERT_EQ(std::vector<std::string>(res.columns().begin(), res.columns().end()), want);
  ASSERT_EQ(res.samples_size(), 4);
  // The probe's columns come after the scene's, the medium's first.
  SceneSpec plain;
  plain.scene = SceneKind::Cell;
  const int medium = static_cast<int>(sampleColumns(plain).size());
  ASSERT_EQ(want[medium], "diss_medium_nw");
  EXPECT_TRUE(std::isnan(res.samples(0).values(medium)));
  for (int k = 1; k < res.samples_size(); ++k) {
    ASSERT_EQ(res.samples(k).values_size(), static_cast<int>(want.size()));
    EXPECT_GT(res.samples(k).values(medium), 0);
  }
  // The job's record holds the key, and a spec that sets it where it means nothing is refused.
  EXPECT_EQ(nlohmann::json::parse(job.spec_json())["observe"]["dissipation"], true);
  v1::SubmitJobRequest bad = tinyCell(3);
  bad.mutable_spec()->mutable_observe()->set_rigid_motion(true);
  v1::SubmitJobResponse resp;
  auto c2 = ctx();
  const grpc::Status st = stub_->SubmitJob(c2.get(), bad, &resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("observe.rigid_motion"), std::string::npos)
      << st.error_message();

  // A probe's curves and final values reach GetResults by name, beside the run's MSRD: a fusion
  // of 3 + 4 cells whose every cell is on the surface (so its surface pairs are all its pairs).
  v1::SubmitJobRequest fr;
  auto* f = fr.mutable_spec();
  f->set_duration_s(4);
  f->set_sample_every_s(1);
  f->set_snapshot_every_s(0);
  f->mutable_numerics()->set_triangles_per_cell(80);
  f->mutable_numerics()->set_dt_s(0.2);  // within the limit of motile cells of 80 triangles
  f->mutable_fusion()->set_n_cells_a(3);
  f->mutable_fusion()->set_n_cells_b(4);
  f->mutable_fusion()->set_prep_max_s(10);
  f->mutable_fusion()->set_allow_uncompacted(true);
  f->mutable_observe()->set_msrd_by_depth(true);
  const std::string fid = submit(fr);
  const v1::Job fjob = waitFor(fid, terminal, 120);
  ASSERT_EQ(fjob.state(), v1::JOB_STATE_SUCCEEDED) << fjob.reason();
  const v1::JobResults fres = results(fid);
  std::map<std::string, const v1::Curve*> curves;
  for (const v1::Curve& c : fres.curves()) curves[c.name()] = &c;
  for (const char* name : {"msrd", "msrd_surface", "msrd_mixed", "msrd_buried", "msrd_layer0",
                           "msrd_layer1", "msrd_layer2plus"})
    EXPECT_TRUE(curves.count(name)) << name;
  ASSERT_TRUE(curves.count("msrd") && curves.count("msrd_surface"));
  const v1::Curve &all = *curves["msrd"], &surface = *curves["msrd_surface"];
  ASSERT_GT(all.x_size(), 0);
  ASSERT_EQ(surface.x_size(), all.x_size());
  for (int k = 0; k < all.x_size(); ++k) {
    EXPECT_EQ(surface.x(k), all.x(k));
    EXPECT_NEAR(surface.y(k), all.y(k), 1e-12 * all.y(k));
  }
  EXPECT_EQ(curves["msrd_buried"]->x_size(), 0);
  std::map<std::string, double> values;
  for (const auto& r : fres.results()) values[r.name()] = r.value();
  EXPECT_EQ(values.at("mixing_time_surface_s"), values.at("mixing_time_s"));
  EXPECT_TRUE(std::isnan(values.at("mixing_time_buried_s")));
}

TEST_F(ServiceTest, CancelWhileRunning) {
  startServer();
  const std::string id = submit(tinyCell(1e6));  // would take minutes
  EXPECT_FALSE(waitFor(id, running).terminal());
  v1::CancelJobRequest cr;
  cr.set_job_id(id);
  cr.set_reason("test cancels it");
  v1::Job j;
  auto c = ctx();
  ASSERT_TRUE(stub_->CancelJob(c.get(), cr, &j).ok());
  j = waitFor(id, terminal, 10);
  EXPECT_EQ(j.state(), v1::JOB_STATE_CANCELLED);
  EXPECT_TRUE(j.terminal());  // the API says so: clients keep no list of end states
  EXPECT_EQ(j.reason(), "test cancels it");
  EXPECT_GT(j.t_s(), 0);
}

TEST_F(ServiceTest, CancelQueuedJob) {
  startServer(/*start_pool=*/false);
  const std::string id = submit(tinyCell());
  v1::CancelJobRequest cr;
  cr.set_job_id(id);
  v1::Job j;
  auto c = ctx();
  ASSERT_TRUE(stub_->CancelJob(c.get(), cr, &j).ok());
  EXPECT_EQ(j.state(), v1::JOB_STATE_CANCELLED);
  EXPECT_TRUE(j.terminal());
}

TEST_F(ServiceTest, IdempotentResubmitReturnsTheSameId) {
  startServer(false);
  v1::SubmitJobRequest r = tinyCell();
  r.set_idempotency_key("run-42");
  v1::SubmitJobResponse a, b;
  auto c1 = ctx();
  ASSERT_TRUE(stub_->SubmitJob(c1.get(), r, &a).ok());
  auto c2 = ctx();
  ASSERT_TRUE(stub_->SubmitJob(c2.get(), r, &b).ok());
  EXPECT_EQ(a.job_id(), b.job_id());
  EXPECT_TRUE(a.created());
  EXPECT_FALSE(b.created());
  EXPECT_EQ(store_->countRows("jobs"), 1);
  // The same key with another spec is refused.
  r.mutable_spec()->set_seed(99);
  auto c3 = ctx();
  EXPECT_EQ(stub_->SubmitJob(c3.get(), r, &b).error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(store_->countRows("jobs"), 1);
}

// SubmitSweep likewise: the same request again gets its sweep, another grid under the same key
// is refused (it was answered with the old sweep in silence).
TEST_F(ServiceTest, IdempotentSweepResubmitAndAReusedKeyRefused) {
  startServer(false);
  v1::SubmitSweepRequest r;
  *r.mutable_spec() = tinyCell().spec();
  r.set_idempotency_key("sweep-7");
  auto* g = r.add_grid();
  g->set_key("cells.gamma");
  g->add_values("0.4");
  g->add_values("0.6");
  v1::SubmitSweepResponse a, b;
  auto c1 = ctx();
  ASSERT_TRUE(stub_->SubmitSweep(c1.get(), r, &a).ok());
  auto c2 = ctx();
  ASSERT_TRUE(stub_->SubmitSweep(c2.get(), r, &b).ok());
  EXPECT_EQ(a.sweep_id(), b.sweep_id());
  EXPECT_EQ(store_->countRows("jobs"), 2);
  r.mutable_grid(0)->set_values(1, "0.7");
  auto c3 = ctx();
  const grpc::Status st = stub_->SubmitSweep(c3.get(), r, &b);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << st.error_message();
  EXPECT_NE(st.error_message().find("with a different request"), std::string::npos)
      << st.error_message();
  EXPECT_EQ(store_->countRows("jobs"), 2);
}

TEST_F(ServiceTest, PaginationAndFilters) {
  startServer(false);  // jobs stay queued
  std::set<std::string> all;
  for (int i = 1; i <= 7; ++i) {
    v1::SubmitJobRequest r = tinyCell();
    r.mutable_spec()->set_seed(static_cast<std::uint64_t>(i));
    r.set_tag(i % 2 ? "odd" : "even");
    all.insert(submit(r));
  }
  std::set<std::string> seen;
  std::string token;
  int pages = 0;
  do {
    v1::ListJobsRequest lr;
    lr.set_page_size(3);
    lr.set_page_token(token);
    v1::ListJobsResponse resp;
    auto c = ctx();
    ASSERT_TRUE(stub_->ListJobs(c.get(), lr, &resp).ok());
    EXPECT_EQ(resp.total(), 7);
    for (const auto& j : resp.jobs())
      EXPECT_TRUE(seen.insert(j.id()).second) << "twice: " << j.id();
    token = resp.next_page_token();
    ++pages;
  } while (!token.empty() && pages < 10);
  EXPECT_EQ(pages, 3);
  EXPECT_EQ(seen, all);

  auto count = [&](const v1::ListJobsRequest& lr) {
    v1::ListJobsResponse resp;
    auto c = ctx();
    const grpc::Status st = stub_->ListJobs(c.get(), lr, &resp);
    EXPECT_TRUE(st.ok()) << st.error_message();
    return resp.jobs_size();
  };
  v1::ListJobsRequest by_tag;
  by_tag.set_tag("odd");
  EXPECT_EQ(count(by_tag), 4);
  v1::ListJobsRequest by_seed;
  auto* p = by_seed.add_params();
  p->set_key("seed");
  p->set_min(2);
  p->set_max(4);
  EXPECT_EQ(count(by_seed), 3);
  v1::ListJobsRequest by_param;
  auto* q = by_param.add_params();
  q->set_key("cells.gamma");
  q->set_min(0.5);
  q->set_max(0.5);
  by_param.add_states(v1::JOB_STATE_QUEUED);
  EXPECT_EQ(count(by_param), 7);
  v1::ListJobsRequest none;
  none.add_states(v1::JOB_STATE_RUNNING);
  EXPECT_EQ(count(none), 0);
  // Bad filters and tokens are INVALID_ARGUMENT.
  v1::ListJobsRequest bad;
  bad.add_params()->set_key("nonsense");
  v1::ListJobsResponse resp;
  auto c = ctx();
  EXPECT_EQ(stub_->ListJobs(c.get(), bad, &resp).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  v1::ListJobsRequest bad_token;
  bad_token.set_page_token("xyz");
  auto c2 = ctx();
  EXPECT_EQ(stub_->ListJobs(c2.get(), bad_token, &resp).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
}

TEST_F(ServiceTest, WatchResumeFromSequenceLosesNothing) {
  startServer();
  v1::SubmitJobRequest r = tinyCell(400);  // 4000 steps: several progress and sample events
  r.mutable_spec()->set_sample_every_s(10);
  const std::string id = submit(r);
  // Read a few events live, drop the stream, resume from the last sequence number seen.
  std::vector<v1::JobEvent> got = watch(id, 0, 3);
  ASSERT_EQ(got.size(), 3u);
  const std::vector<v1::JobEvent> rest = watch(id, got.back().seq());
  got.insert(got.end(), rest.begin(), rest.end());
  const std::vector<v1::JobEvent> full = watch(id, 0);
  ASSERT_EQ(got.size(), full.size());
  for (std::size_t i = 0; i < full.size(); ++i) {
    EXPECT_EQ(got[i].seq(), static_cast<std::int64_t>(i + 1));
    EXPECT_EQ(got[i].SerializeAsString(), full[i].SerializeAsString()) << "event " << i + 1;
  }
  EXPECT_EQ(full.back().state().state(), v1::JOB_STATE_SUCCEEDED);
  // Resuming from the middle of a finished job gives exactly the tail.
  const std::vector<v1::JobEvent> tail = watch(id, 5);
  ASSERT_EQ(tail.size(), full.size() - 5);
  EXPECT_EQ(tail.front().seq(), 6);
}

TEST_F(ServiceTest, InvalidSpecsAreInvalidArgumentNamingTheFieldAndStoreUnchanged) {
  startServer(false);
  struct Case {
    const char* field;  // expected in the message
    std::function<void(v1::SubmitJobRequest&)> edit;
  };
  const std::vector<Case> cases = {
      {"scene", [](auto& r) { r.mutable_spec()->clear_scene(); }},
      {"duration_s", [](auto& r) { r.mutable_spec()->set_duration_s(-1); }},
      {"duration_s", [](auto& r) { r.mutable_spec()->set_duration_s(0); }},
      {"sample_every_s", [](auto& r) { r.mutable_spec()->set_sample_every_s(-5); }},
      {"sample_every_s", [](auto& r) { r.mutable_spec()->set_sample_every_s(100); }},
      {"snapshot_every_s", [](auto& r) { r.mutable_spec()->set_snapshot_every_s(-1); }},
      {"cells.gamma", [](auto& r) { r.mutable_spec()->mutable_cells()->set_gamma(0); }},
      {"cells.gamma", [](auto& r) { r.mutable_spec()->mutable_cells()->set_gamma(std::nan("")); }},
      {"cells.eta", [](auto& r) { r.mutable_spec()->mutable_cells()->set_eta(-3); }},
      {"cells.alpha", [](auto& r) { r.mutable_spec()->mutable_cells()->set_alpha(1.5); }},
      {"cells.radius_mean_um",
       [](auto& r) { r.mutable_spec()->mutable_cells()->set_radius_mean_um(0); }},
      {"cells.bulk_modulus",
       [](auto& r) { r.mutable_spec()->mutable_cells()->set_bulk_modulus(-1); }},
      {"cells.k_contact", [](auto& r) { r.mutable_spec()->mutable_cells()->set_k_contact(-1); }},
      {"cells.tau_p_s", [](auto& r) { r.mutable_spec()->mutable_cells()->set_tau_p_s(-1); }},
      {"cells.eta_m", [](auto& r) { r.mutable_spec()->mutable_cells()->set_eta_m(-1); }},
      {"numerics.dt_s", [](auto& r) { r.mutable_spec()->mutable_numerics()->set_dt_s(0); }},
      {"numerics.dt_s",
       [](auto& r) {
         r.mutable_spec()->mutable_numerics()->set_dt_s(std::numeric_limits<double>::infinity());
       }},
      {"numerics.cg_tol", [](auto& r) { r.mutable_spec()->mutable_numerics()->set_cg_tol(0); }},
      {"numerics.triangles_per_cell",
       [](auto& r) { r.mutable_spec()->mutable_numerics()->set_triangles_per_cell(100); }},
      {"numerics.cg_max_iter",
       [](auto& r) { r.mutable_spec()->mutable_numerics()->set_cg_max_iter(-1); }},
      {"scene.axes_ratio", [](auto& r) { r.mutable_spec()->mutable_cell()->set_axes_ratio(-2); }},
      {"seed", [](auto& r) { r.mutable_spec()->set_seed(~0ULL); }},
      {"cells.gamma", [](auto& r) { r.add_settings("cells.gamma=abc"); }},
      {"cells.gama", [](auto& r) { r.add_settings("cells.gama=0.5"); }},
      {"spec_text", [](auto& r) { r.set_spec_text("scene = \"cell\"\nduration_s = [oops"); }},
      {"spec_text", [](auto& r) { r.set_spec_text(std::string(300 * 1024, '#')); }},
      {"idempotency_key", [](auto& r) { r.set_idempotency_key(std::string(1000, 'k')); }},
  };
  ASSERT_GE(cases.size(), 20u);
  const auto jobs0 = store_->countRows("jobs");
  const auto events0 = store_->countRows("events");
  for (const Case& cs : cases) {
    v1::SubmitJobRequest r = tinyCell();
    cs.edit(r);
    v1::SubmitJobResponse resp;
    auto c = ctx();
    const grpc::Status st = stub_->SubmitJob(c.get(), r, &resp);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << cs.field;
    EXPECT_NE(st.error_message().find(cs.field), std::string::npos)
        << "expected '" << cs.field << "' in: " << st.error_message();
    // ResolveSpec checks a spec as a submit does, with the same message.
    if (std::string(cs.field) == "idempotency_key") continue;  // a submit's field only
    v1::ResolveSpecRequest q;
    *q.mutable_spec() = r.spec();
    q.set_spec_text(r.spec_text());
    *q.mutable_settings() = r.settings();
    v1::ResolveSpecResponse qr;
    auto c2 = ctx();
    const grpc::Status rs = stub_->ResolveSpec(c2.get(), q, &qr);
    EXPECT_EQ(rs.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << cs.field;
    EXPECT_EQ(rs.error_message(), st.error_message());
    EXPECT_TRUE(qr.spec_json().empty());
  }
  EXPECT_EQ(store_->countRows("jobs"), jobs0);
  EXPECT_EQ(store_->countRows("events"), events0);
}

// A job stored by an earlier version is served read by today's engine: its record (spec_json)
// as stored, and beside it resolved_spec_json in today's keys — the contact law the two switches
// named, every key added since at the value its run had (the key table's `before`, not today's
// default), the rest as stored — by every call that answers with the job.
TEST_F(ServiceTest, AnEarlierVersionsRecordIsServedInTodaysKeys) {
  startServer(false);
  const EarlierRecord old = earlierDoublet();
  ASSERT_TRUE(jsonAt(old.record, "numerics.contact_law").is_null());
  NewJob job;
  job.spec = old.spec;
  job.spec_json = old.record.dump();
  job.tag = "earlier";
  const std::string id = store_->submit(job).first;

  const v1::Job j = get(id);
  EXPECT_EQ(j.spec_json(), old.record.dump());
  ASSERT_FALSE(j.resolved_spec_json().empty());
  const nlohmann::json now = nlohmann::json::parse(j.resolved_spec_json());
  EXPECT_EQ(now["numerics"]["contact_law"], "prisms-overlap");
  EXPECT_FALSE(now["numerics"].contains("contact_within_prisms"));
  EXPECT_FALSE(now["numerics"].contains("contact_prisms_overlap_only"));
  int added_since = 0;
  for (const SpecField& f : specFields()) {
    if (f.before && f.key != "numerics.contact_law") {
      ++added_since;
      EXPECT_EQ(jsonAt(now, f.key), asJson(*f.before)) << f.key;
    } else if (!f.before) {
      EXPECT_EQ(jsonAt(now, f.key), jsonAt(old.rest, f.key)) << f.key;
    }
  }
  EXPECT_GE(added_since, 5);
  // Today's defaults of some of those keys are not the values the run had: read at `before`,
  // the record is another run than today's spec of the same settings.
  EXPECT_NE(now, old.rest);

  v1::ListJobsRequest lr;
  lr.set_tag("earlier");
  v1::ListJobsResponse list;
  auto c1 = ctx();
  ASSERT_TRUE(stub_->ListJobs(c1.get(), lr, &list).ok());
  ASSERT_EQ(list.jobs_size(), 1);
  EXPECT_EQ(list.jobs(0).resolved_spec_json(), j.resolved_spec_json());
  EXPECT_EQ(results(id, false).job().resolved_spec_json(), j.resolved_spec_json());
  const std::vector<v1::JobEvent> events = watch(id, 0, 1);
  ASSERT_FALSE(events.empty());
  ASSERT_TRUE(events[0].has_state());
  EXPECT_EQ(events[0].state().resolved_spec_json(), j.resolved_spec_json());
  v1::CancelJobRequest cr;
  cr.set_job_id(id);
  v1::Job cancelled;
  auto c3 = ctx();
  ASSERT_TRUE(stub_->CancelJob(c3.get(), cr, &cancelled).ok());
  EXPECT_EQ(cancelled.resolved_spec_json(), j.resolved_spec_json());
}

// The labels of a record only name what its other keys hold: served as the record named them
// where this engine reads the name, else null (never the default the reading left in place). A
// record this engine cannot read is served without a resolved spec.
TEST_F(ServiceTest, ARecordsLabelsAreItsOwnAndAnUnreadableRecordHasNoResolvedSpec) {
  startServer(false);
  EarlierRecord old = earlierDoublet();
  auto serve = [&](const nlohmann::json& record) {
    NewJob job;
    job.spec = old.spec;
    job.spec_json = record.dump();
    return get(store_->submit(job).first);
  };
  nlohmann::json record = old.record;
  record["numerics"]["preset"] = "reference";
  record["accuracy"]["contact_angle_deg"] = 2.0;
  nlohmann::json now = nlohmann::json::parse(serve(record).resolved_spec_json());
  EXPECT_EQ(now["numerics"]["preset"], "reference");
  EXPECT_EQ(now["numerics"]["dt_s"], 0.5);  // the record's, not the preset's 0.25 s
  EXPECT_EQ(now["accuracy"]["contact_angle_deg"], 2.0);
  EXPECT_TRUE(now["accuracy"]["trajectory_deg"].is_null());
  record["numerics"]["preset"] = "draft";  // retired: no step cheaper than standard was fit
  now = nlohmann::json::parse(serve(record).resolved_spec_json());
  EXPECT_TRUE(now["numerics"]["preset"].is_null());
  EXPECT_EQ(now["numerics"]["dt_s"], 0.5);
  eraseAt(record, "numerics.preset");
  now = nlohmann::json::parse(serve(record).resolved_spec_json());
  EXPECT_TRUE(now["numerics"]["preset"].is_null());

  // The facing bound was retired at its neutral 90°: a record at 60° is no run this engine makes.
  record["numerics"]["contact_max_facing_deg"] = 60.0;
  const v1::Job unreadable = serve(record);
  EXPECT_EQ(unreadable.spec_json(), record.dump());
  EXPECT_TRUE(unreadable.resolved_spec_json().empty());
  record["numerics"]["contact_max_facing_deg"] = 90.0;
  EXPECT_FALSE(serve(record).resolved_spec_json().empty());
}

// ResolveSpec answers with the spec a submit of the same fields stores, and creates nothing; a
// job submitted today is served its own record as resolved spec.
TEST_F(ServiceTest, ResolveSpecAnswersWhatASubmitStoresAndCreatesNoJob) {
  startServer(false);
  v1::SubmitJobRequest sub = tinyCell();
  sub.add_settings("numerics.preset=reference");
  sub.add_settings("numerics.triangles_per_cell=80");
  sub.set_spec_text("[cells]\neta = 6\n");
  v1::ResolveSpecRequest req;
  *req.mutable_spec() = sub.spec();
  req.set_spec_text(sub.spec_text());
  *req.mutable_settings() = sub.settings();
  v1::ResolveSpecResponse resp;
  auto c = ctx();
  const grpc::Status st = stub_->ResolveSpec(c.get(), req, &resp);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(store_->countRows("jobs"), 0);
  const nlohmann::json resolved = nlohmann::json::parse(resp.spec_json());
  EXPECT_EQ(resolved["numerics"]["dt_s"], 0.1);     // given, so the preset leaves it
  EXPECT_EQ(resolved["numerics"]["cg_tol"], 1e-3);  // the reference preset's
  EXPECT_EQ(resolved["cells"]["eta"], 6.0);
  std::set<std::string> labels;
  for (const SpecField& f : specFields())
    if (f.label) labels.insert(f.key);
  EXPECT_EQ(std::set<std::string>(resp.labels().begin(), resp.labels().end()), labels);
  EXPECT_TRUE(labels.count("numerics.preset"));

  const v1::Job j = get(submit(sub));
  EXPECT_EQ(nlohmann::json::parse(j.spec_json()), resolved);
  EXPECT_EQ(nlohmann::json::parse(j.resolved_spec_json()), resolved);

  // The earlier switches, given as settings, resolve to the law they name.
  v1::ResolveSpecRequest old;
  old.add_settings("scene=doublet");
  old.add_settings("numerics.dt_s=0.5");
  old.add_settings("numerics.contact_within_prisms=false");
  auto c2 = ctx();
  const grpc::Status st2 = stub_->ResolveSpec(c2.get(), old, &resp);
  ASSERT_TRUE(st2.ok()) << st2.error_message();
  EXPECT_EQ(nlohmann::json::parse(resp.spec_json())["numerics"]["contact_law"], "supplement");

  // A fusion prepared at values of its own: the record stored and served holds them, resolved.
  v1::SubmitJobRequest fusion;
  fusion.mutable_spec()->mutable_fusion();
  fusion.add_settings("cells.l_eta_reduced=2");
  fusion.add_settings("prepare.cells.l_eta_reduced=0.5");
  v1::ResolveSpecRequest fq;
  *fq.mutable_settings() = fusion.settings();
  *fq.mutable_spec() = fusion.spec();
  auto c3 = ctx();
  const grpc::Status st3 = stub_->ResolveSpec(c3.get(), fq, &resp);
  ASSERT_TRUE(st3.ok()) << st3.error_message();
  const nlohmann::json prepared = nlohmann::json::parse(resp.spec_json());
  EXPECT_GT(prepared["prepare"]["cells"]["xi"], prepared["cells"]["xi"]);
  const v1::Job fj = get(submit(fusion));
  EXPECT_EQ(nlohmann::json::parse(fj.spec_json()), prepared);
  EXPECT_EQ(nlohmann::json::parse(fj.resolved_spec_json()), prepared);
}

TEST_F(ServiceTest, TokenAuth) {
  startServer(false, "s3cret");
  v1::ListJobsRequest lr;
  v1::ListJobsResponse resp;
  auto none = ctx();
  EXPECT_EQ(stub_->ListJobs(none.get(), lr, &resp).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  auto wrong = ctx("guess");
  EXPECT_EQ(stub_->ListJobs(wrong.get(), lr, &resp).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  v1::SubmitJobResponse sresp;
  auto wrong2 = ctx("s3cre");
  EXPECT_EQ(stub_->SubmitJob(wrong2.get(), tinyCell(), &sresp).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(store_->countRows("jobs"), 0);
  auto right = ctx("s3cret");
  const grpc::Status st = stub_->ListJobs(right.get(), lr, &resp);
  EXPECT_TRUE(st.ok()) << st.error_message();
  auto right2 = ctx("s3cret");
  EXPECT_TRUE(stub_->SubmitJob(right2.get(), tinyCell(), &sresp).ok());
}

TEST_F(ServiceTest, SnapshotLargerThan4MiBStreamsInChunks) {
  startServer(false);
  const std::string id = submit(tinyCell());
  // 6 MiB of incompressible data stored as one snapshot (as a big fusion snapshot would be).
  std::string big(6 * 1024 * 1024, '\0');
  std::mt19937_64 rng(1);
  for (char& ch : big) ch = static_cast<char>(rng());
  v1::SnapshotInfo info;
  info.set_t_s(1);
  info.set_bytes(static_cast<std::int64_t>(big.size()));
  store_->addSnapshot(id, info, "", big);
  store_->flush();
  v1::GetSnapshotRequest gr;
  gr.set_job_id(id);
  gr.set_index(-1);
  grpc::ClientContext c;
  auto reader = stub_->GetSnapshot(&c, gr);
  v1::SnapshotChunk chunk;
  std::string data;
  int chunks = 0;
  std::int64_t total = -1;
  while (reader->Read(&chunk)) {
    if (chunks++ == 0) total = chunk.total_bytes();
    data += chunk.data();
  }
  ASSERT_TRUE(reader->Finish().ok());
  EXPECT_GT(chunks, 4);
  EXPECT_EQ(total, static_cast<std::int64_t>(big.size()));
  EXPECT_TRUE(data == big);
}

TEST_F(ServiceTest, RecordedSnapshotsOfARunCanBeFetched) {
  startServer();
  v1::SubmitJobRequest r = tinyCell();
  r.mutable_spec()->set_snapshot_every_s(1);
  const std::string id = submit(r);
  waitFor(id, terminal);
  v1::GetSnapshotRequest gr;
  gr.set_job_id(id);
  gr.set_index(0);
  grpc::ClientContext c;
  auto reader = stub_->GetSnapshot(&c, gr);
  v1::SnapshotChunk chunk;
  v1::SnapshotInfo info;
  int n = 0;
  while (reader->Read(&chunk))
    if (n++ == 0) info = chunk.info();
  ASSERT_TRUE(reader->Finish().ok());
  EXPECT_EQ(info.triangles(), 80);
  EXPECT_EQ(info.vertices(), 42);
}

// Requests that used to be accepted silently or answered opaquely: each is
// INVALID_ARGUMENT naming the field, a huge value is not echoed back whole, and the server
// keeps serving.
TEST_F(ServiceTest, BadRequestsAreInvalidArgumentNamingTheField) {
  startServer();
  const std::string id = submit(tinyCell());
  waitFor(id, terminal);
  auto expectInvalid = [](const grpc::Status& st, const std::string& field) {
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
    EXPECT_EQ(st.error_message().rfind(field, 0), 0u) << st.error_message();
  };
  {
    v1::ListJobsRequest lr;
    lr.add_states(static_cast<v1::JobState>(99));
    v1::ListJobsResponse resp;
    auto c = ctx();
    expectInvalid(stub_->ListJobs(c.get(), lr, &resp), "states: 99 is not a job state");
  }
  {
    v1::QueryResultsRequest q;
    auto* p = q.add_params();
    p->set_key("gamma");
    p->set_min(std::nan(""));
    v1::QueryResultsResponse resp;
    auto c = ctx();
    expectInvalid(stub_->QueryResults(c.get(), q, &resp), "params['gamma'].min: NaN");
    q.clear_params();
    q.set_limit(-1);
    auto c2 = ctx();
    expectInvalid(stub_->QueryResults(c2.get(), q, &resp), "limit: -1 is outside [0, 100000]");
  }
  {
    v1::GetSnapshotRequest gr;
    gr.set_job_id(id);
    gr.set_index(-2);
    grpc::ClientContext c;
    auto reader = stub_->GetSnapshot(&c, gr);
    v1::SnapshotChunk chunk;
    while (reader->Read(&chunk)) {
    }
    expectInvalid(reader->Finish(), "index: -2 is below -1");
  }
  {
    // 2 MiB of spec: under the transport's limit (16 MiB), so the answer names the field and
    // the spec's own limit (before: gRPC's RESOURCE_EXHAUSTED once past 4 MiB).
    v1::SubmitJobRequest big = tinyCell();
    big.set_spec_text(std::string(2 << 20, '#'));
    v1::SubmitJobResponse resp;
    auto c = ctx();
    expectInvalid(stub_->SubmitJob(c.get(), big, &resp),
                  "invalid spec: spec_text: too large: 2097152 bytes, at most 262144");
  }
  {
    v1::GetJobRequest gj;
    gj.set_job_id(std::string(64 * 1024, 'x'));
    v1::Job j;
    auto c = ctx();
    const grpc::Status st = stub_->GetJob(c.get(), gj, &j);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::NOT_FOUND);
    EXPECT_LT(st.error_message().size(), 300u) << "the 64 KB id is not echoed whole";
    EXPECT_NE(st.error_message().find("(65536 bytes)"), std::string::npos) << st.error_message();
  }
  v1::ListJobsResponse resp;
  auto c = ctx();
  ASSERT_TRUE(stub_->ListJobs(c.get(), v1::ListJobsRequest(), &resp).ok());
  EXPECT_EQ(resp.jobs_size(), 1);
}

TEST_F(ServiceTest, SweepCreatesGridTimesSeedsJobs) {
  startServer(false);
  v1::SubmitSweepRequest sr;
  *sr.mutable_spec() = tinyCell().spec();
  auto* g1 = sr.add_grid();
  g1->set_key("cells.eta");
  g1->add_values("3");
  g1->add_values("5");
  auto* g2 = sr.add_grid();
  g2->set_key("cells.gamma");
  g2->add_values("0.4");
  g2->add_values("0.6");
  sr.add_seeds(1);
  sr.add_seeds(2);
  v1::SubmitSweepResponse resp;
  auto c = ctx();
  ASSERT_TRUE(stub_->SubmitSweep(c.get(), sr, &resp).ok());
  EXPECT_EQ(resp.job_ids_size(), 8);
  v1::ListJobsRequest lr;
  lr.set_sweep_id(resp.sweep_id());
  auto* p = lr.add_params();
  p->set_key("eta");
  p->set_min(4);
  v1::ListJobsResponse lresp;
  auto c2 = ctx();
  ASSERT_TRUE(stub_->ListJobs(c2.get(), lr, &lresp).ok());
  EXPECT_EQ(lresp.total(), 4);
  // One invalid set: nothing is created.
  const auto jobs0 = store_->countRows("jobs");
  g2->add_values("-1");
  auto c3 = ctx();
  const grpc::Status st = stub_->SubmitSweep(c3.get(), sr, &resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("cells.gamma"), std::string::npos);
  EXPECT_EQ(store_->countRows("jobs"), jobs0);
}

// Every string the API stores has a cap, the same on every RPC and named in the
// error; a sweep's job count is capped through its seeds too (1000 values × 101 seeds made
// 101 000 jobs). Nothing is stored by a refused request.
TEST_F(ServiceTest, EveryStoredStringAndSweepSizeIsCapped) {
  startServer();
  const auto jobs0 = store_->countRows("jobs");
  auto expectRefused = [&](const grpc::Status& st, const std::string& field) {
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << field;
    EXPECT_NE(st.error_message().find(field), std::string::npos) << st.error_message();
  };
  // CancelJob: a 2 KiB reason.
  const std::string id = submit(tinyCell(1000));
  v1::CancelJobRequest cr;
  cr.set_job_id(id);
  cr.set_reason(std::string(2048, 'r'));
  v1::Job j;
  {
    auto c = ctx();
    expectRefused(stub_->CancelJob(c.get(), cr, &j), "reason: at most 1024 bytes");
  }
  cr.set_reason(std::string(1024, 'r'));  // at the cap: accepted
  {
    auto c = ctx();
    EXPECT_TRUE(stub_->CancelJob(c.get(), cr, &j).ok());
  }
  // SubmitSweep: tag, name and idempotency key as SubmitJob's.
  v1::SubmitSweepRequest base;
  *base.mutable_spec() = tinyCell().spec();
  base.add_seeds(1);
  v1::SubmitSweepResponse resp;
  for (const std::string field : {"tag", "name", "idempotency_key"}) {
    v1::SubmitSweepRequest r = base;
    const std::string big(257, 'x');
    if (field == "tag") r.set_tag(big);
    if (field == "name") r.set_name(big);
    if (field == "idempotency_key") r.set_idempotency_key(big);
    auto c = ctx();
    expectRefused(stub_->SubmitSweep(c.get(), r, &resp), field + ": at most 256 bytes");
  }
  // 1000 values × 101 seeds: refused before a spec is converted.
  v1::SubmitSweepRequest r = base;
  auto* g = r.add_grid();
  g->set_key("cells.gamma");
  for (int k = 0; k < 1000; ++k) g->add_values(std::to_string(0.3 + k * 1e-4));
  for (int s = 2; s <= 101; ++s) r.add_seeds(static_cast<std::uint64_t>(s));
  {
    auto c = ctx();
    expectRefused(stub_->SubmitSweep(c.get(), r, &resp), "more than the 100000 jobs");
  }
  // Three 300-value axes: 27 million sets, counted from the axes before any is built — refused
  // at once, and the server goes on serving.
  {
    v1::SubmitSweepRequest huge = base;
    for (const char* key : {"cells.alpha", "cells.gamma", "cells.eta"}) {
      auto* axis = huge.add_grid();
      axis->set_key(key);
      for (int k = 0; k < 300; ++k) axis->add_values(std::to_string(0.3 + k * 1e-4));
    }
    const auto t0 = std::chrono::steady_clock::now();
    auto c = ctx();
    expectRefused(stub_->SubmitSweep(c.get(), huge, &resp),
                  "grid × seeds: 27000000 parameter sets × 1 seeds, more than the 100000 jobs");
    EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(1));
    EXPECT_FALSE(get(submit(tinyCell())).id().empty());
  }
  EXPECT_EQ(store_->countRows("jobs"), jobs0 + 2);  // the two cell jobs only
  EXPECT_EQ(store_->countRows("sweeps"), 0);
}

TEST_F(ServiceTest, QueryResultsFiltersByParameters) {
  startServer();
  std::vector<std::string> ids;
  for (double gamma : {0.4, 0.6}) {
    v1::SubmitJobRequest r = tinyCell();
    r.mutable_spec()->mutable_cells()->set_gamma(gamma);
    r.mutable_spec()->set_snapshot_every_s(2);
    ids.push_back(submit(r));
  }
  for (const auto& id : ids) waitFor(id, terminal);
  v1::QueryResultsRequest q;
  auto* p = q.add_params();
  p->set_key("gamma");
  p->set_min(0.5);
  q.add_names("aspect_ratio");
  v1::QueryResultsResponse resp;
  auto c = ctx();
  ASSERT_TRUE(stub_->QueryResults(c.get(), q, &resp).ok());
  ASSERT_EQ(resp.rows_size(), 1);
  EXPECT_EQ(resp.rows(0).job_id(), ids[1]);
  ASSERT_EQ(resp.rows(0).results_size(), 1);
  EXPECT_EQ(resp.rows(0).results(0).name(), "aspect_ratio");
  EXPECT_DOUBLE_EQ(resp.rows(0).params().at("gamma"), 0.6);
}

namespace {

// The standard services, called without generated stubs (their messages hand-encoded: the
// Debian gRPC library already holds the reflection descriptors).
grpc::Status healthCheck(grpc::GenericStub& stub, const std::string& service, std::string* reply) {
  std::string req;
  if (!service.empty()) req = std::string("\x0a") + static_cast<char>(service.size()) + service;
  const grpc::ByteBuffer request = bytes(req);
  grpc::ByteBuffer response;
  grpc::ClientContext c;
  c.set_deadline(std::chrono::system_clock::now() + 10s);
  std::promise<grpc::Status> done;
  stub.UnaryCall(&c, "/grpc.health.v1.Health/Check", grpc::StubOptions(), &request, &response,
                 [&](grpc::Status st) { done.set_value(st); });
  const grpc::Status st = done.get_future().get();
  *reply = bytes(response);
  return st;
}

// activefoam.v1.Foam's serving status as the health reply encodes it (kServing, kNotServing),
// or the call's error.
const std::string kServing("\x08\x01", 2), kNotServing("\x08\x02", 2);
std::string foamHealth(const std::shared_ptr<grpc::Channel>& channel) {
  grpc::GenericStub generic(channel);
  std::string reply;
  const grpc::Status st = healthCheck(generic, "activefoam.v1.Foam", &reply);
  return st.ok() ? reply : "error: " + st.error_message();
}

}  // namespace

// Strings that are not UTF-8, and bytes that are not a message at all: protobuf refuses both,
// and gRPC's callback server used to answer UNIMPLEMENTED with no message (foam: exit 3,
// "server unreachable"). Now INVALID_ARGUMENT naming the field, and the server keeps serving.
TEST_F(ServiceTest, RequestsThatAreNotUtf8OrNotAMessageAreInvalidArgumentNamingTheField) {
  startServer();
  auto expectInvalid = [](const grpc::Status& st, const std::string& message) {
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
    EXPECT_EQ(st.error_message(), message);
  };
  {
    v1::GetJobRequest r;
    r.set_job_id("j-\xff\xfe");
    v1::Job j;
    auto c = ctx();
    expectInvalid(stub_->GetJob(c.get(), r, &j), "job_id: not valid UTF-8 (byte 2)");
  }
  {
    v1::SubmitJobRequest r = tinyCell();
    r.add_settings("duration_s=5");
    r.add_settings("tag=caf\xe9");
    v1::SubmitJobResponse resp;
    auto c = ctx();
    expectInvalid(stub_->SubmitJob(c.get(), r, &resp), "settings[1]: not valid UTF-8 (byte 7)");
  }
  {
    v1::QueryResultsRequest q;
    q.add_params()->set_key("gamma");
    q.add_params()->set_key("\xc0\xaf");  // an overlong '/'
    v1::QueryResultsResponse resp;
    auto c = ctx();
    expectInvalid(stub_->QueryResults(c.get(), q, &resp),
                  "params[1].key: not valid UTF-8 (byte 0)");
  }
  {
    v1::WatchJobRequest w;
    w.set_job_id("\x80");
    grpc::ClientContext c;
    c.set_deadline(std::chrono::system_clock::now() + 10s);
    auto reader = stub_->WatchJob(&c, w);
    v1::JobEvent ev;
    EXPECT_FALSE(reader->Read(&ev));
    expectInvalid(reader->Finish(), "job_id: not valid UTF-8 (byte 0)");
  }
  {
    // Field 1 announces 16 bytes, 3 follow.
    grpc::GenericStub generic(channel_);
    const grpc::ByteBuffer request =
        bytes(std::string("\x0a\x10"
                          "abc",
                          5));
    grpc::ByteBuffer response;
    grpc::ClientContext c;
    c.set_deadline(std::chrono::system_clock::now() + 10s);
    std::promise<grpc::Status> done;
    generic.UnaryCall(&c, "/activefoam.v1.Foam/GetJob", grpc::StubOptions(), &request, &response,
                      [&](grpc::Status st) { done.set_value(st); });
    expectInvalid(done.get_future().get(),
                  "malformed request: 5 bytes that are not a activefoam.v1.GetJobRequest message");
  }
  // Well-formed requests are untouched, and the server still serves.
  const std::string id = submit(tinyCell());
  EXPECT_EQ(get(id).id(), id);
}

// Disk full mid-run: every write fails with SQLITE_FULL for a while. The server
// does not abort; it logs, counts the failures, reports NOT_SERVING and refuses new submits
// while still answering reads; the running job's queued outputs are kept and committed when
// space returns, and it ends with the samples of an uninterrupted run.
TEST_F(ServiceTest, StoreWriteFailuresAreRetriedAndTheJobEndsIntact) {
  faulty_vfs::install();
  startServer();
  v1::SubmitJobRequest spec = tinyCell(20000);  // ~3.5 s of wall time
  spec.mutable_spec()->set_sample_every_s(250);
  const std::string ref = submit(spec);
  ASSERT_EQ(waitFor(ref, terminal).state(), v1::JOB_STATE_SUCCEEDED);

  const std::string id = submit(spec);
  waitFor(id, [](const v1::Job& j) { return j.state() == v1::JOB_STATE_RUNNING && j.t_s() > 0; });
  faulty_vfs::fail_writes = true;
  for (int i = 0; i < 200 && !store_->degraded(); ++i) std::this_thread::sleep_for(10ms);
  ASSERT_TRUE(store_->degraded()) << "a running job's writes reach the store within 2 s";
  std::this_thread::sleep_for(300ms);
  EXPECT_GT(store_->storeErrors(), 0);
  EXPECT_NE(store_->lastError().find("full"), std::string::npos) << store_->lastError();
  EXPECT_EQ(foamHealth(channel_), kNotServing);
  v1::SubmitJobResponse resp;
  auto c = ctx();
  const grpc::Status refused = stub_->SubmitJob(c.get(), tinyCell(), &resp);
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_NE(refused.error_message().find("the store cannot write"), std::string::npos)
      << refused.error_message();
  EXPECT_EQ(get(id).id(), id) << "reads are served";

  faulty_vfs::fail_writes = false;
  const v1::Job done = waitFor(id, terminal);
  EXPECT_EQ(done.state(), v1::JOB_STATE_SUCCEEDED) << done.reason();
  EXPECT_FALSE(store_->degraded());
  EXPECT_EQ(foamHealth(channel_), kServing) << "SERVING again";
  const v1::JobResults a = store_->results(ref, true), b = store_->results(id, true);
  ASSERT_EQ(a.samples_size(), 81);
  ASSERT_EQ(b.samples_size(), a.samples_size());
  for (int k = 0; k < a.samples_size(); ++k) {
    ASSERT_EQ(b.samples(k).values_size(), a.samples(k).values_size());
    for (int v = 0; v < a.samples(k).values_size(); ++v) {
      if (a.columns(v) == "wall_s") continue;
      EXPECT_EQ(b.samples(k).values(v), a.samples(k).values(v)) << k << " " << a.columns(v);
    }
  }
}

// foamd restarted (after kill -9) on a full disk re-queued the jobs left running
// with a write that waited for space, before it listened: neither gRPC nor /healthz answered
// until space returned. Now the start's re-queue is one more write of the writer thread: retried
// while the storage fails, the server listens at once and is degraded (NOT_SERVING, submits
// refused, reads served) until the write commits; then the job resumes and ends.
TEST_F(ServiceTest, StoreWriteFailuresAtStartLeaveTheServerListeningDegraded) {
  faulty_vfs::install();
  startServer(false);
  const std::string id = submit(tinyCell());
  ASSERT_TRUE(store_->claimNext()) << "the job is running when the server dies";
  server_->shutdown();
  server_.reset();
  pool_.reset();  // never started: it re-queues nothing, as kill -9 does not
  store_.reset();

  faulty_vfs::fail_writes = true;
  // What foamd's main does at a start, on a thread: the old start never returned.
  auto started = std::async(std::launch::async, [&] {
    store_ = std::make_unique<Store>(db_.string());
    EXPECT_EQ(store_->requeueRunningInBackground("restarted"), 1);
    PoolOptions po;
    po.workers = 2;
    pool_ = std::make_unique<Pool>(*store_, po);
    ServerConfig config;
    config.listen = "127.0.0.1:0";
    server_ = std::make_unique<FoamServer>(*store_, *pool_, config);
    server_->start();
    pool_->start();
  });
  if (started.wait_for(3s) != std::future_status::ready) {
    faulty_vfs::fail_writes = false;  // let it finish, to fail cleanly
    started.get();
    FAIL() << "the server did not start within 3 s while writes failed";
  }
  started.get();
  channel_ = grpc::CreateChannel("127.0.0.1:" + std::to_string(server_->port()),
                                 grpc::InsecureChannelCredentials());
  stub_ = v1::Foam::NewStub(channel_);
  for (int i = 0; i < 200 && !store_->degraded(); ++i) std::this_thread::sleep_for(10ms);
  ASSERT_TRUE(store_->degraded());
  EXPECT_EQ(foamHealth(channel_), kNotServing);
  v1::SubmitJobResponse resp;
  auto c = ctx();
  EXPECT_EQ(stub_->SubmitJob(c.get(), tinyCell(), &resp).error_code(),
            grpc::StatusCode::UNAVAILABLE);
  EXPECT_EQ(get(id).state(), v1::JOB_STATE_RUNNING) << "reads are served; not re-queued yet";

  faulty_vfs::fail_writes = false;
  const v1::Job done = waitFor(id, terminal);
  EXPECT_EQ(done.state(), v1::JOB_STATE_SUCCEEDED) << done.reason();
  EXPECT_EQ(foamHealth(channel_), kServing) << "SERVING again";
}

TEST_F(ServiceTest, HealthAndReflectionAnswer) {
  startServer(false);
  grpc::GenericStub generic(channel_);
  std::string reply;
  // HealthCheckResponse{status: SERVING} is the two bytes 08 01.
  ASSERT_TRUE(healthCheck(generic, "", &reply).ok());
  EXPECT_EQ(reply, std::string("\x08\x01", 2));
  ASSERT_TRUE(healthCheck(generic, "activefoam.v1.Foam", &reply).ok());
  EXPECT_EQ(reply, std::string("\x08\x01", 2));
  EXPECT_EQ(healthCheck(generic, "no.such.Service", &reply).error_code(),
            grpc::StatusCode::NOT_FOUND);

  // Reflection (v1alpha, what Debian's library serves): list_services names our API.
  grpc::CompletionQueue cq;
  grpc::ClientContext c;
  c.set_deadline(std::chrono::system_clock::now() + 10s);
  auto call = generic.PrepareCall(
      &c, "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo", &cq);
  auto next = [&] {
    void* tag = nullptr;
    bool ok = false;
    return cq.Next(&tag, &ok) && ok;
  };
  call->StartCall(reinterpret_cast<void*>(1));
  ASSERT_TRUE(next());
  call->Write(bytes(std::string("\x3a\x00", 2)), reinterpret_cast<void*>(2));  // list_services ""
  ASSERT_TRUE(next());
  call->WritesDone(reinterpret_cast<void*>(3));
  ASSERT_TRUE(next());
  grpc::ByteBuffer response;
  call->Read(&response, reinterpret_cast<void*>(4));
  ASSERT_TRUE(next());
  const std::string listed = bytes(response);
  EXPECT_NE(listed.find("activefoam.v1.Foam"), std::string::npos);
  EXPECT_NE(listed.find("grpc.health.v1.Health"), std::string::npos);
  grpc::Status st;
  call->Finish(&st, reinterpret_cast<void*>(5));
  ASSERT_TRUE(next());
  EXPECT_TRUE(st.ok()) << st.error_message();
  cq.Shutdown();
  void* tag;
  bool ok;
  while (cq.Next(&tag, &ok)) {
  }
}

TEST_F(ServiceTest, TlsWithTokenRefusesPlainTextAndWrongTokens) {
  startServer(false, "s3cret", /*tls=*/true);
  v1::ListJobsRequest lr;
  v1::ListJobsResponse resp;
  auto right = ctx("s3cret");
  const grpc::Status ok = stub_->ListJobs(right.get(), lr, &resp);
  EXPECT_TRUE(ok.ok()) << ok.error_message();
  auto wrong = ctx("guess");
  EXPECT_EQ(stub_->ListJobs(wrong.get(), lr, &resp).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  // A client speaking plain text, or one not trusting the certificate, gets nowhere.
  auto plain = v1::Foam::NewStub(grpc::CreateChannel(addr_, grpc::InsecureChannelCredentials()));
  auto c1 = ctx("s3cret");
  c1->set_deadline(std::chrono::system_clock::now() + 3s);
  EXPECT_FALSE(plain->ListJobs(c1.get(), lr, &resp).ok());
  auto untrusting = v1::Foam::NewStub(
      grpc::CreateChannel(addr_, grpc::SslCredentials(grpc::SslCredentialsOptions())));
  auto c2 = ctx("s3cret");
  c2->set_deadline(std::chrono::system_clock::now() + 3s);
  EXPECT_FALSE(untrusting->ListJobs(c2.get(), lr, &resp).ok());
}

TEST_F(ServiceTest, HttpServesJobsResultsAndMetricsWithFilters) {
  startServer();
  std::vector<std::string> ids;
  for (double gamma : {0.4, 0.6}) {
    v1::SubmitJobRequest r = tinyCell();
    r.mutable_spec()->mutable_cells()->set_gamma(gamma);
    r.mutable_spec()->set_snapshot_every_s(2);
    r.set_tag(gamma < 0.5 ? "low" : "high");
    ids.push_back(submit(r));
  }
  for (const auto& id : ids) waitFor(id, terminal);
  HttpEndpoint http(*store_, *pool_, "127.0.0.1:0");
  int code = 0;
  std::string type;
  auto get = [&](const std::string& path) {
    const std::string body = http.handle(path, code, type);
    return nlohmann::json::parse(body);
  };
  EXPECT_EQ(get("/jobs").at("jobs").size(), 2u);
  EXPECT_EQ(code, 200);
  auto j = get("/jobs?tag=high");
  ASSERT_EQ(j.at("jobs").size(), 1u);
  EXPECT_EQ(j.at("jobs")[0].at("id"), ids[1]);
  EXPECT_EQ(get("/jobs?state=succeeded,failed&param.gamma=0.3:0.5").at("jobs").size(), 1u);
  EXPECT_EQ(get("/jobs?state=queued").at("jobs").size(), 0u);
  j = get("/jobs?page_size=1");
  EXPECT_EQ(j.at("jobs").size(), 1u);
  EXPECT_FALSE(j.at("next_page_token").get<std::string>().empty());
  j = get("/jobs?page_size=1&page_token=" + j.at("next_page_token").get<std::string>());
  EXPECT_EQ(j.at("jobs").size(), 1u);
  j = get("/results?param.gamma=0.5:&names=aspect_ratio");
  ASSERT_EQ(j.at("rows").size(), 1u);
  EXPECT_EQ(j.at("rows")[0].at("job_id"), ids[1]);
  EXPECT_EQ(get("/jobs/" + ids[0]).at("id"), ids[0]);
  EXPECT_FALSE(get("/jobs/" + ids[0] + "/samples").at("rows").empty());
  // Bad queries name the parameter; unknown pages are 404.
  for (const char* bad : {"/jobs?state=sleeping", "/jobs?page_size=0", "/jobs?colour=red",
                          "/results?param.gamma=abc", "/jobs?param.=1"}) {
    const std::string err = get(bad).at("error");
    EXPECT_EQ(code, 400) << bad;
    EXPECT_NE(err.find("query parameter"), std::string::npos) << bad << ": " << err;
  }
  get("/jobs/nope");
  EXPECT_EQ(code, 404);
  const std::string metrics = http.handle("/metrics", code, type);
  EXPECT_NE(metrics.find("foamd_jobs{state=\"JOB_STATE_SUCCEEDED\"} 2"), std::string::npos)
      << metrics;
  EXPECT_NE(metrics.find("foamd_steps_total"), std::string::npos);

  // The samples as CSV: the columns, then one line per sample, equal to the JSON values.
  const std::string csv = http.handle("/jobs/" + ids[0] + "/samples.csv", code, type);
  EXPECT_EQ(code, 200);
  EXPECT_EQ(type, "text/csv");
  const nlohmann::json samples = get("/jobs/" + ids[0] + "/samples");
  std::istringstream lines(csv);
  std::string line;
  std::getline(lines, line);
  EXPECT_EQ(line.rfind("t_s,steps,", 0), 0u) << line;
  std::size_t rows = 0;
  for (; std::getline(lines, line); ++rows) {
    ASSERT_LT(rows, samples.at("rows").size());
    EXPECT_DOUBLE_EQ(std::stod(line.substr(0, line.find(','))),
                     samples.at("rows")[rows][0].get<double>());
  }
  EXPECT_EQ(rows, samples.at("rows").size());
  // The newest snapshot (and snapshot 0) as VTK PolyData: a closed 80-triangle cell.
  const v1::JobResults res = store_->results(ids[0], false);
  ASSERT_GE(res.snapshots_size(), 2);
  for (const std::string which : {"latest", "0"}) {
    const std::string vtp =
        http.handle("/jobs/" + ids[0] + "/snapshots/" + which + ".vtp", code, type);
    ASSERT_EQ(code, 200) << vtp;
    const activefoam::VtkMesh mesh = activefoam::readVtp(vtp);
    EXPECT_EQ(mesh.tri.size(), 80u);
    EXPECT_DOUBLE_EQ(mesh.t_s, which == "latest" ? res.snapshots().rbegin()->t_s() : 0.0);
    // The same snapshot in the 3D view's binary form (server/mesh_frame.h): one cell, so its
    // vertices and triangles keep their order; positions as float32.
    const std::string bin =
        http.handle("/jobs/" + ids[0] + "/snapshots/" + which + ".mesh", code, type);
    ASSERT_EQ(code, 200) << bin;
    EXPECT_EQ(type, "application/octet-stream");
    ASSERT_GT(bin.size(), 8u);
    EXPECT_EQ(bin.substr(0, 4), "AFM1");
    std::uint32_t hlen = 0;
    std::memcpy(&hlen, bin.data() + 4, 4);
    const nlohmann::json h = nlohmann::json::parse(bin.substr(8, hlen));
    EXPECT_EQ(h.at("index").get<int>(), which == "latest" ? res.snapshots().rbegin()->index() : 0);
    EXPECT_DOUBLE_EQ(h.at("t_s").get<double>(), mesh.t_s);
    const std::size_t nv = mesh.points.size() / 3, nt = mesh.tri.size();
    EXPECT_EQ(h.at("vertices").get<std::size_t>(), nv);
    EXPECT_EQ(h.at("triangles").get<std::size_t>(), nt);
    EXPECT_EQ(h.at("cells").get<int>(), 1);
    EXPECT_EQ(h.at("vertex_start"), nlohmann::json({0, nv}));
    EXPECT_EQ(h.at("triangle_start"), nlohmann::json({0, nt}));
    EXPECT_EQ(h.at("pressure_kPa").size(), 1u);
    const auto pos_off = h.at("positions_offset").get<std::size_t>();
    const auto tri_off = h.at("triangles_offset").get<std::size_t>();
    EXPECT_EQ(pos_off, 8 + hlen);
    EXPECT_EQ(pos_off % 4, 0u);
    EXPECT_EQ(tri_off, pos_off + 12 * nv);
    ASSERT_EQ(bin.size(), tri_off + 12 * nt);
    for (std::size_t k = 0; k < 3 * nv; ++k) {
      float x = 0;
      std::memcpy(&x, bin.data() + pos_off + 4 * k, 4);
      ASSERT_EQ(x, static_cast<float>(mesh.points[k])) << k;
    }
    for (std::size_t k = 0; k < 3 * nt; ++k) {
      std::uint32_t v = 0;
      std::memcpy(&v, bin.data() + tri_off + 4 * k, 4);
      ASSERT_EQ(v, static_cast<std::uint32_t>(mesh.tri[k / 3][k % 3])) << k;
    }
  }
  http.handle("/jobs/" + ids[0] + "/snapshots/99.mesh", code, type);
  EXPECT_EQ(code, 404);
  http.handle("/jobs/" + ids[0] + "/snapshots/x.mesh", code, type);
  EXPECT_EQ(code, 400);
  http.handle("/jobs/" + ids[0] + "/snapshots/99.vtp", code, type);
  EXPECT_EQ(code, 404);
  http.handle("/jobs/" + ids[0] + "/snapshots/-1.vtp", code, type);
  EXPECT_EQ(code, 400);
  http.handle("/jobs/nope/snapshots/latest.vtp", code, type);
  EXPECT_EQ(code, 404);

  // Over the socket (cpp-httplib answers HTTP/1.1), GET only.
  auto request = [&](const std::string& line) {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(http.port()));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    const std::string req = line + "\r\nHost: 127.0.0.1\r\n\r\n";
    EXPECT_EQ(send(fd, req.data(), req.size(), 0), static_cast<ssize_t>(req.size()));
    std::string resp;
    char buf[4096];
    for (ssize_t n; (n = recv(fd, buf, sizeof buf, 0)) > 0;) resp.append(buf, n);
    close(fd);
    return resp;
  };
  const std::string r1 = request("GET /jobs?tag=low HTTP/1.0");
  EXPECT_EQ(r1.rfind("HTTP/1.1 200 OK", 0), 0u) << r1;
  EXPECT_NE(r1.find(ids[0]), std::string::npos);
  EXPECT_EQ(r1.find(ids[1]), std::string::npos);
  const std::string r2 = request("POST /jobs HTTP/1.0\r\nContent-Length: 0");
  EXPECT_EQ(r2.rfind("HTTP/1.1 405", 0), 0u) << r2;
  EXPECT_NE(r2.find("GET only"), std::string::npos) << r2;
}
