// The coordinator service's own replies (issue 40): one real gRPC server on loopback in this process
// (CoordinatorService over a SweepCoordinator on a fresh data directory: real SQLite index, real HDF5 maps),
// called through the project's client and through the raw stub.
// - auth in one place: every method of the service's descriptor refuses a call without a token, and a token
//   of the wrong role, before it reads the request (a method added without going through Serve fails here);
// - the spec travels once per sweep to a worker: a lease names its key, and leaves the text out when the
//   request names that key; hostile key lists are refused naming the field and the bound; a worker that
//   lacks the spec gets it (GetSpec, key checked); two sweeps, a coordinator restart and a worker restart;
// - published maps are read once (MapCache) for GetMap, ListMetrics and the dashboard together, and read
//   again when the map file is replaced.
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <thread>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include "base/sha256.h"
#include "bistable.grpc.pb.h"
#include "engine/evaluate.h"
#include "engine/sweep_spec.h"
#include "proto/convert.h"
#include "proto/coordinator_client.h"
#include "server/coordinator_service.h"
#include "server/dashboard.h"
#include "server/map_cache.h"
#include "storage/map_file.h"
#include "tests/process_util.h"
#include "worker/grpc_job_source.h"
#include "worker/pull_loop.h"

namespace bistable {
namespace {

namespace fs = std::filesystem;

// Sweeps of other lengths or t_end share no items (whose stored results would be reused, not leased).
std::string SpecText(int n, const std::string& name, int t_end = 40) {
  return "name = \"" + name + "\"\nmodel = \"coupled\"\n[axes]\nalpha = { linspace = [0.2, 2.5, " + std::to_string(n) +
         "] }\nomega = { linspace = [0.3, 2.0, 4] }\n[integration]\nt_end = " + std::to_string(t_end) +
         ".0\nt_keep = 20.0\n";
}

// A coordinator and its service on 127.0.0.1 (port 0: any; or the port of a previous server, to restart).
struct Server {
  std::unique_ptr<SweepCoordinator> coord;
  std::unique_ptr<CoordinatorService> service;
  std::unique_ptr<grpc::Server> server;
  std::shared_ptr<MapCache> maps = std::make_shared<MapCache>();
  int port = 0;

  Server(const std::string& data, TokenStore tokens = {}, int want_port = 0) {
    auto c = SweepCoordinator::Open(data, {.lease_seconds = 60, .resume = true, .log = false});
    EXPECT_TRUE(c.ok()) << c.status().ToString();
    coord = std::move(c).value();
    service = std::make_unique<CoordinatorService>(coord.get(), 60, 0.01, std::move(tokens), maps);
    grpc::ServerBuilder b;
    ConfigureServerBuilder(b);
    b.AddListeningPort("127.0.0.1:" + std::to_string(want_port), grpc::InsecureServerCredentials(), &port);
    b.RegisterService(service.get());
    server = b.BuildAndStart();
    EXPECT_TRUE(server != nullptr && port > 0);
  }
  ~Server() {
    service->Shutdown();
    server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(5));
  }
  std::string address() const { return "127.0.0.1:" + std::to_string(port); }
  std::unique_ptr<CoordinatorClient> Client(const std::string& token = "") const {
    auto c = CoordinatorClient::Connect(ConnectOptions{address(), "", token});
    EXPECT_TRUE(c.ok()) << c.status().ToString();
    return std::move(c).value();
  }
  std::unique_ptr<v1::Coordinator::Stub> Stub() const {
    return v1::Coordinator::NewStub(grpc::CreateChannel(address(), grpc::InsecureChannelCredentials()));
  }
};

std::string FreshDir(const std::string& name) { return bistable_test::FreshDir("service", name); }

std::string Submit(CoordinatorClient& c, const std::string& spec) {
  auto s = c.Submit(spec, "test.toml");
  EXPECT_TRUE(s.ok()) << s.status().ToString();
  return s.ok() ? s->id : "";
}

// ---------------------------------------------------------------------------------------------------
// Auth in one place

TEST(Service, EveryMethodChecksTheTokenBeforeTheRequest) {
  const std::string dir = FreshDir("auth");
  const std::string viewer = "viewer-token-0123456789", worker = "worker-token-0123456789";
  const std::string tokens_file = dir + "/tokens";
  {
    std::ofstream f(tokens_file);
    f << "viewer " << Sha256Hex(viewer) << " v\nworker " << Sha256Hex(worker) << " w\n";
  }
  ::chmod(tokens_file.c_str(), 0600);
  auto tokens = TokenStore::Load(tokens_file);
  ASSERT_TRUE(tokens.ok()) << tokens.status().ToString();
  Server s(dir + "/data", *tokens);
  auto stub = s.Stub();
  // One call per method, with an empty request: the token is what is refused, never the request.
  using Call = std::function<grpc::Status(grpc::ClientContext*)>;
  const std::map<std::string, std::pair<Call, bool>> calls = {
      // method -> (call, a viewer may make it)
      {"Submit",
       {[&](grpc::ClientContext* x) {
          v1::SubmitReply r;
          return stub->Submit(x, {}, &r);
        },
        false}},
      {"GetStatus",
       {[&](grpc::ClientContext* x) {
          v1::SweepStatus r;
          return stub->GetStatus(x, {}, &r);
        },
        true}},
      {"WatchStatus",
       {[&](grpc::ClientContext* x) {
          v1::SweepStatus r;
          auto rd = stub->WatchStatus(x, {});
          while (rd->Read(&r)) {
          }
          return rd->Finish();
        },
        true}},
      {"Cancel",
       {[&](grpc::ClientContext* x) {
          v1::CancelReply r;
          return stub->Cancel(x, {}, &r);
        },
        false}},
      {"ListSweeps",
       {[&](grpc::ClientContext* x) {
          v1::ListSweepsReply r;
          return stub->ListSweeps(x, {}, &r);
        },
        true}},
      {"GetMap",
       {[&](grpc::ClientContext* x) {
          v1::MapReply r;
          return stub->GetMap(x, {}, &r);
        },
        true}},
      {"ListMetrics",
       {[&](grpc::ClientContext* x) {
          v1::MetricsReply r;
          return stub->ListMetrics(x, {}, &r);
        },
        true}},
      {"RegisterWorker",
       {[&](grpc::ClientContext* x) {
          v1::RegisterReply r;
          return stub->RegisterWorker(x, {}, &r);
        },
        false}},
      {"Lease",
       {[&](grpc::ClientContext* x) {
          v1::LeaseReply r;
          return stub->Lease(x, {}, &r);
        },
        false}},
      {"Heartbeat",
       {[&](grpc::ClientContext* x) {
          v1::HeartbeatReply r;
          return stub->Heartbeat(x, {}, &r);
        },
        false}},
      {"Report",
       {[&](grpc::ClientContext* x) {
          v1::ReportReply r;
          return stub->Report(x, {}, &r);
        },
        false}},
      {"Release",
       {[&](grpc::ClientContext* x) {
          v1::ReleaseReply r;
          return stub->Release(x, {}, &r);
        },
        false}},
      {"ListWorkers",
       {[&](grpc::ClientContext* x) {
          v1::ListWorkersReply r;
          return stub->ListWorkers(x, {}, &r);
        },
        true}},
      {"FetchMap",
       {[&](grpc::ClientContext* x) {
          v1::FileChunk r;
          auto rd = stub->FetchMap(x, {});
          while (rd->Read(&r)) {
          }
          return rd->Finish();
        },
        true}},
      {"GetSpec",
       {[&](grpc::ClientContext* x) {
          v1::SpecReply r;
          return stub->GetSpec(x, {}, &r);
        },
        false}},
  };
  const auto* service =
      google::protobuf::DescriptorPool::generated_pool()->FindServiceByName(v1::Coordinator::service_full_name());
  ASSERT_NE(service, nullptr);
  std::set<std::string> seen;
  for (int i = 0; i < service->method_count(); ++i) {
    const std::string m = service->method(i)->name();
    seen.insert(m);
    auto it = calls.find(m);
    ASSERT_NE(it, calls.end()) << "method " << m << " has no row in this test";
    {
      grpc::ClientContext x;
      x.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
      const grpc::Status st = it->second.first(&x);
      EXPECT_EQ(st.error_code(), grpc::StatusCode::UNAUTHENTICATED) << m << ": " << st.error_message();
    }
    // The role that may not make it is refused as such; the one that may gets past the token to the request.
    for (const auto& [token, is_viewer] : {std::pair{viewer, true}, std::pair{worker, false}}) {
      grpc::ClientContext x;
      x.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
      x.AddMetadata("authorization", "Bearer " + token);
      const grpc::Status st = it->second.first(&x);
      const bool allowed = is_viewer ? it->second.second : (!it->second.second && m != "Submit" && m != "Cancel");
      if (allowed)
        EXPECT_NE(st.error_code(), grpc::StatusCode::PERMISSION_DENIED)
            << m << " refused a " << (is_viewer ? "viewer" : "worker");
      else
        EXPECT_EQ(st.error_code(), grpc::StatusCode::PERMISSION_DENIED)
            << m << " let a " << (is_viewer ? "viewer" : "worker") << " in";
    }
  }
  EXPECT_EQ(seen.size(), calls.size()) << "a row of this test names no method of the service";
}

// ---------------------------------------------------------------------------------------------------
// The spec once per sweep

TEST(Service, ALeaseLeavesOutTheSpecAWorkerNamesAsHeld) {
  const std::string dir = FreshDir("spec_once");
  Server s(dir + "/data");
  auto client = s.Client();
  const std::string text = SpecText(16, "once");  // 64 items: jobs of at most 8 items, so several
  const std::string id = Submit(*client, text);
  auto stub = s.Stub();
  auto lease = [&](const std::vector<std::string>& known) {
    v1::LeaseRequest req;
    req.set_worker("w1");
    for (const auto& k : known) req.add_known_specs(k);
    v1::LeaseReply rep;
    grpc::ClientContext x;
    EXPECT_TRUE(stub->Lease(&x, req, &rep).ok());
    EXPECT_TRUE(rep.has_job());
    EXPECT_EQ(rep.sweep_id(), id);
    return rep;
  };
  // An old worker names nothing: the text, as before, and its key beside it.
  const v1::LeaseReply first = lease({});
  EXPECT_EQ(first.spec_toml(), text);
  EXPECT_EQ(first.spec_key(), SpecKey(text));
  // A worker that holds it: the key only.
  const v1::LeaseReply second = lease({SpecKey("another spec"), first.spec_key()});
  EXPECT_EQ(second.spec_toml(), "");
  EXPECT_EQ(second.spec_key(), first.spec_key());
  // Another key does not stand for it.
  EXPECT_EQ(lease({SpecKey("another spec")}).spec_toml(), text);

  // Report-and-lease-next names them too.
  auto records = ComputeItems(*ParseSweepSpec(text, "t"), *ItemsFromProto(second));
  v1::ReportRequest rr;
  rr.set_lease_id(second.lease_id());
  ToProto(records, &rr);
  rr.set_lease_next_for("w1");
  rr.add_next_known_specs(first.spec_key());
  v1::ReportReply rp;
  grpc::ClientContext x;
  ASSERT_TRUE(stub->Report(&x, rr, &rp).ok());
  ASSERT_TRUE(rp.next().has_job());
  EXPECT_EQ(rp.next().spec_toml(), "");
  EXPECT_EQ(rp.next().spec_key(), first.spec_key());
}

TEST(Service, HostileSpecKeysAreRefusedNamingTheFieldAndTheBound) {
  const std::string dir = FreshDir("spec_hostile");
  Server s(dir + "/data");
  auto client = s.Client();
  const std::string id = Submit(*client, SpecText(6, "hostile"));
  auto stub = s.Stub();
  auto lease = [&](const std::vector<std::string>& known) {
    v1::LeaseRequest req;
    req.set_worker("w1");
    for (const auto& k : known) req.add_known_specs(k);
    v1::LeaseReply rep;
    grpc::ClientContext x;
    return stub->Lease(&x, req, &rep);
  };
  grpc::Status st = lease(std::vector<std::string>(17, SpecKey("x")));
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("known_specs"), std::string::npos) << st.error_message();
  EXPECT_NE(st.error_message().find("16"), std::string::npos) << st.error_message();
  for (const std::string& bad : {std::string(), std::string(64, 'G'), SpecKey("x") + "0", std::string(1 << 20, 'a')}) {
    st = lease({SpecKey("ok"), bad});
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(st.error_message().find("known_specs[1]"), std::string::npos) << st.error_message();
  }
  // Refused before anything is leased: the sweep's first lease is still the first job.
  v1::LeaseRequest ok;
  ok.set_worker("w1");
  v1::LeaseReply rep;
  {
    grpc::ClientContext x;
    ASSERT_TRUE(stub->Lease(&x, ok, &rep).ok());
  }
  EXPECT_EQ(rep.job_id(), 0);
  // A report with a bad list is refused whole, before it is stored; the same report then is accepted.
  v1::ReportRequest rr;
  rr.set_lease_id(rep.lease_id());
  ToProto(ComputeItems(*ParseSweepSpec(rep.spec_toml(), "t"), *ItemsFromProto(rep)), &rr);
  rr.set_lease_next_for("w1");
  rr.add_next_known_specs("not a key");
  v1::ReportReply rp;
  {
    grpc::ClientContext x;
    st = stub->Report(&x, rr, &rp);
  }
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("next_known_specs[0]"), std::string::npos) << st.error_message();
  EXPECT_EQ(s.coord->progress(id).items_done, 0);
  rr.clear_next_known_specs();
  {
    grpc::ClientContext x;
    EXPECT_TRUE(stub->Report(&x, rr, &rp).ok());
  }
  // GetSpec: whole hex ids only; an unknown one is not found.
  for (const std::string& bad : {std::string(), std::string("ABC"), std::string(65, 'a'), std::string("ab/..")}) {
    v1::SpecRequest q;
    q.set_sweep_id(bad);
    v1::SpecReply a;
    grpc::ClientContext x;
    st = stub->GetSpec(&x, q, &a);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << bad;
    EXPECT_NE(st.error_message().find("sweep_id"), std::string::npos) << st.error_message();
  }
  v1::SpecRequest q;
  q.set_sweep_id("0123456789ab");
  v1::SpecReply a;
  grpc::ClientContext x;
  EXPECT_EQ(stub->GetSpec(&x, q, &a).error_code(), grpc::StatusCode::NOT_FOUND);
}

TEST(Service, AWorkerThatLacksTheSpecGetsIt) {
  const std::string dir = FreshDir("spec_lacking");
  Server s(dir + "/data");
  auto client = s.Client();
  const std::string text = SpecText(6, "lacking");
  const std::string id = Submit(*client, text);
  // Names a key it does not hold (its cache lost it between the request and the reply).
  auto lease = client->LeaseJob("w1", 1, {SpecKey(text)});
  ASSERT_TRUE(lease.ok() && lease->has_value()) << lease.status().ToString();
  EXPECT_EQ((*lease)->spec_toml, "");
  SpecCache cache;
  auto spec = SpecOfLease(client.get(), &cache, **lease);
  ASSERT_TRUE(spec.ok()) << spec.status().ToString();
  EXPECT_EQ((*spec)->source, text);
  EXPECT_EQ(cache.parses(), 1);
  EXPECT_EQ(cache.Keys(), std::vector<std::string>{SpecKey(text)});
  // A lease whose key is not its text's is refused, not cached under the wrong key.
  CoordinatorClient::Lease forged = **lease;
  forged.spec_toml = SpecText(5, "other");
  SpecCache empty;
  EXPECT_FALSE(SpecOfLease(client.get(), &empty, forged).ok());
  EXPECT_TRUE(empty.Keys().empty());
}

TEST(Service, TwoSweepsAndRestartsParseEachSpecOncePerWorker) {
  const std::string dir = FreshDir("spec_restarts");
  auto s = std::make_unique<Server>(dir + "/data");
  const int port = s->port;
  auto client = s->Client();
  const std::string a = Submit(*client, SpecText(16, "a")), b = Submit(*client, SpecText(12, "b"));
  SpecCache cache;
  {
    GrpcJobSource source(client.get(), "w1", &cache, 1);
    // Three jobs, one of them with report-and-lease-next.
    for (int i = 0; i < 3; ++i) {
      auto job = source.Lease();
      ASSERT_TRUE(job.ok() && job->has_value()) << job.status().ToString();
      std::optional<LeasedJob> next;
      ASSERT_TRUE(source.Report(**job, ComputeItems(*(*job)->spec, (*job)->items), i == 1 ? &next : nullptr).ok());
      if (next) {
        ASSERT_TRUE(source.Report(*next, ComputeItems(*next->spec, next->items), nullptr).ok());
      }
    }
  }
  EXPECT_EQ(cache.parses(), 1);  // sweep a's spec
  // The coordinator restarts (same port): it holds nothing of the worker, which names what it holds.
  s.reset();
  s = std::make_unique<Server>(dir + "/data", TokenStore{}, port);
  GrpcJobSource source(client.get(), "w1", &cache, 4);
  bool done = false;
  for (int i = 0; i < 200 && !done; ++i) {
    auto job = source.Lease();
    if (!job.ok()) {  // the channel reconnects to the restarted coordinator
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      continue;
    }
    if (!job->has_value()) {
      done = true;
      break;
    }
    ASSERT_TRUE(source.Report(**job, ComputeItems(*(*job)->spec, (*job)->items), nullptr).ok());
  }
  EXPECT_TRUE(done);
  EXPECT_EQ(cache.parses(), 2);  // a's and b's specs, once each, across the coordinator's restart
  EXPECT_EQ(cache.Keys().size(), 2u);
  // A restarted worker holds nothing, names nothing and is sent the text.
  const std::string c = Submit(*client, SpecText(4, "c", 41));
  SpecCache fresh;
  GrpcJobSource again(client.get(), "w2", &fresh, 1);
  auto job = again.Lease();
  ASSERT_TRUE(job.ok() && job->has_value()) << job.status().ToString();
  EXPECT_EQ(fresh.parses(), 1);
  EXPECT_EQ((*job)->spec->Id(), c);
  (void)a, (void)b;
}

// ---------------------------------------------------------------------------------------------------
// Published maps read once

// Runs sweep `id` to its published map through the coordinator; the map file's path.
std::string Publish(SweepCoordinator* c, const std::string& id, const SweepSpec& spec) {
  while (auto l = c->Lease("w", id, 16)) EXPECT_TRUE(c->Report(l->lease_id, ComputeItems(spec, l->items)).ok());
  auto path = c->Publish(id);
  EXPECT_TRUE(path.ok()) << path.status().ToString();
  return path.ok() ? *path : "";
}

TEST(Service, PublishedMapsAreReadOnceForTheServiceAndTheDashboard) {
  const std::string dir = FreshDir("map_cache");
  Server s(dir + "/data");
  auto client = s.Client();
  const std::string text = SpecText(6, "maps");
  const std::string id = Submit(*client, text);
  const std::string path = Publish(s.coord.get(), id, *ParseSweepSpec(text, "t"));
  ASSERT_FALSE(path.empty());
  auto direct = ReadMapMetric(path, "frf_db");
  ASSERT_TRUE(direct.ok());

  auto m1 = client->GetMap(id, "frf_db");
  ASSERT_TRUE(m1.ok()) << m1.status().ToString();
  const long after_first = s.maps->loads();
  EXPECT_EQ(after_first, 2);  // the metric list (the name is checked against it) and the metric
  auto m2 = client->GetMap(id, "frf_db");
  auto names = client->ListMetrics(id);
  ASSERT_TRUE(m2.ok() && names.ok());
  EXPECT_EQ(s.maps->loads(), after_first);
  EXPECT_EQ(m1->values, direct->values);
  EXPECT_EQ(m2->values, direct->values);
  EXPECT_EQ(names->metrics, *ListMapMetrics(path));
  // An unknown or hostile metric name: ReadMapMetric's answer, nothing read or kept for it.
  for (const std::string& bad : {std::string("nope"), std::string("/axes/alpha"), std::string(100, 'm')}) {
    auto r = client->GetMap(id, bad);
    EXPECT_FALSE(r.ok());
    EXPECT_NE(r.status().ToString().find(ReadMapMetric(path, bad).status().message()), std::string::npos)
        << r.status().ToString();
  }
  EXPECT_EQ(s.maps->loads(), after_first);

  // The dashboard, given the same cache, reads nothing again.
  TokenStore open;
  auto routes = DashboardRoutes(s.coord.get(), &open, {}, s.maps);
  HttpRequest req;
  req.path = "/api/map";
  req.query = "id=" + id + "&metric=frf_db";
  req.host = "127.0.0.1";
  req.peer = "127.0.0.1";
  const HttpResponse r = routes.at("/api/map")(req);
  EXPECT_EQ(r.status, 200) << r.body;
  EXPECT_EQ(s.maps->loads(), after_first);

  // The map file replaced (as a republication does: written beside, renamed): read again, once.
  fs::copy_file(path, path + ".tmp");
  fs::rename(path + ".tmp", path);
  auto m3 = client->GetMap(id, "frf_db");
  ASSERT_TRUE(m3.ok());
  EXPECT_EQ(m3->values, direct->values);
  EXPECT_EQ(s.maps->loads(), after_first + 2);
  EXPECT_EQ(routes.at("/api/map")(req).status, 200);
  EXPECT_TRUE(client->GetMap(id, "frf_db").ok());
  EXPECT_EQ(s.maps->loads(), after_first + 2);
}

TEST(Service, TheMapCacheIsBounded) {
  const std::string dir = FreshDir("map_bound");
  Server s(dir + "/data");
  auto client = s.Client();
  const std::string text = SpecText(6, "bound");
  const std::string id = Submit(*client, text);
  const std::string path = Publish(s.coord.get(), id, *ParseSweepSpec(text, "t"));
  auto names = ListMapMetrics(path);
  ASSERT_TRUE(names.ok() && names->size() > 4);
  MapCache small(3, 1 << 20);
  for (const auto& n : *names) ASSERT_TRUE(small.Metric(path, n).ok()) << n;
  EXPECT_LE(small.entries(), 3u);
  EXPECT_LE(small.bytes(), size_t{1} << 20);
  MapCache tiny(16, 64);  // every metric is larger than the bound: served, never kept
  auto m = tiny.Metric(path, "frf_db");
  ASSERT_TRUE(m.ok());
  EXPECT_EQ((*m)->values, ReadMapMetric(path, "frf_db")->values);
  EXPECT_EQ(tiny.bytes(), 0u);
  EXPECT_TRUE(tiny.Metric(path, "frf_db").ok());
  EXPECT_EQ(tiny.loads(), 4);  // the list (over 64 bytes too) and the metric, each time
}

}  // namespace
}  // namespace bistable
