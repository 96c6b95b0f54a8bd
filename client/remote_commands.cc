// `bistable submit | status | cancel | workers`: the client side of the distributed service.
#include <chrono>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>

#include <grpcpp/grpcpp.h>
#include <nlohmann/json.hpp>

#include "bistable.grpc.pb.h"
#include "base/file.h"
#include "base/limits.h"
#include "client/cli_common.h"
#include "client/progress.h"
#include "client/remote_commands.h"
#include "proto/channel.h"
#include "proto/status_convert.h"
#include "server/auth.h"

namespace bistable {
namespace {

using v1::Coordinator;

ConnectOptions g_conn;

std::unique_ptr<Coordinator::Stub> Connect(const std::string&) {
  auto ch = MakeChannel(g_conn);
  return Coordinator::NewStub(ch.ok() ? *ch : grpc::CreateChannel(g_conn.address, grpc::InsecureChannelCredentials()));
}

std::unique_ptr<grpc::ClientContext> Ctx(double seconds = 30) { return CallContext(g_conn, seconds); }

int RpcFail(const grpc::Status& s, const std::string& addr) {
  Status st = FromGrpcStatus(s);
  if (s.error_code() == grpc::StatusCode::UNAVAILABLE || s.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED)
    st = Status::IoError("coordinator", "cannot reach " + addr + " (" + s.error_message() + ")");
  return Fail(st);
}

nlohmann::json StatusJson(const v1::SweepStatus& s) {
  return {{"id", s.id()}, {"state", s.state()}, {"points_done", s.points_done()}, {"points_total", s.points_total()},
          {"points_cached", s.points_cached()}, {"workers", s.workers()}, {"seconds", s.seconds()}, {"file", s.file()},
          {"name", s.name()}, {"model", s.model()}, {"error", s.error()}};
}

struct RemoteArgs {
  std::string coordinator = "127.0.0.1:50051", target, token_file, tls_ca;
  bool json = false, watch = false;
};

// Resolves the connection options (token, CA) once per command; errors name the flag.
Status Prepare(const RemoteArgs& a) {
  auto token = LoadToken(a.token_file);
  if (!token.ok()) return token.status();
  g_conn = {a.coordinator, a.tls_ca, *token};
  if (!a.tls_ca.empty()) {
    auto ch = MakeChannel(g_conn);
    if (!ch.ok()) return ch.status();
  }
  return Status::Ok();
}

int Submit(const RemoteArgs& a) {
  auto text = ReadTextFile(a.target, "spec", limits::kMaxSpecBytes);
  if (!text.ok()) return Fail(text.status());
  v1::SubmitRequest req;
  req.set_spec_toml(*text);
  req.set_origin(a.target);
  v1::SubmitReply rep;
  const grpc::Status s = Connect(a.coordinator)->Submit(Ctx().get(), req, &rep);
  if (!s.ok()) return RpcFail(s, a.coordinator);
  if (a.json) {
    std::cout << nlohmann::json({{"id", rep.id()}, {"items_total", rep.items_total()}, {"items_cached", rep.items_cached()},
                                 {"jobs", rep.jobs()}}).dump() << "\n";
  } else {
    std::cout << rep.id() << "\n";
  }
  return 0;
}

int StatusCmd(const RemoteArgs& a) {
  auto stub = Connect(a.coordinator);
  v1::StatusRequest req;
  req.set_id(a.target);
  if (!a.watch) {
    v1::SweepStatus st;
    const grpc::Status s = stub->GetStatus(Ctx().get(), req, &st);
    if (!s.ok()) return RpcFail(s, a.coordinator);
    if (a.json) std::cout << StatusJson(st).dump() << "\n";
    else
      std::printf("%s  %s  %ld/%ld points (%ld reused)  %d workers  %.1f s  %s\n", st.id().c_str(), st.state().c_str(),
                  static_cast<long>(st.points_done()), static_cast<long>(st.points_total()),
                  static_cast<long>(st.points_cached()), st.workers(), st.seconds(), st.file().c_str());
    if (!a.json && !st.error().empty()) std::printf("  error: %s\n", st.error().c_str());
    return st.state() == "failed" ? 1 : 0;
  }
  auto ctx = Ctx(0);  // no deadline: the stream lasts as long as the sweep
  auto reader = stub->WatchStatus(ctx.get(), req);
  v1::SweepStatus st;
  std::unique_ptr<ProgressBar> bar;
  long base = 0;
  while (reader->Read(&st)) {
    if (a.json) {
      std::cout << StatusJson(st).dump() << std::endl;
      continue;
    }
    if (!bar) {
      base = st.points_done();
      bar = std::make_unique<ProgressBar>(st.points_total() - base, "sweep " + st.id(), true);
    }
    bar->Update(st.points_done() - base, std::to_string(st.workers()) + (st.workers() == 1 ? " worker" : " workers"));
  }
  const grpc::Status s = reader->Finish();
  if (!s.ok()) return RpcFail(s, a.coordinator);
  if (bar) bar->Finish(st.points_done() - base, st.state());
  if (!a.json) std::printf("%s %s (%d workers at the end)%s%s\n", st.id().c_str(), st.state().c_str(), st.workers(),
                           st.file().empty() ? "" : ", map: ", st.file().c_str());
  return st.state() == "done" ? 0 : 1;
}

int CancelCmd(const RemoteArgs& a) {
  v1::CancelRequest req;
  req.set_id(a.target);
  v1::CancelReply rep;
  const grpc::Status s = Connect(a.coordinator)->Cancel(Ctx().get(), req, &rep);
  if (!s.ok()) return RpcFail(s, a.coordinator);
  if (a.json) std::cout << nlohmann::json({{"id", a.target}, {"state", "cancelled"}}).dump() << "\n";
  else std::cout << "cancelled " << a.target << "\n";
  return 0;
}

int WorkersCmd(const RemoteArgs& a) {
  v1::ListWorkersRequest req;
  v1::ListWorkersReply rep;
  const grpc::Status s = Connect(a.coordinator)->ListWorkers(Ctx().get(), req, &rep);
  if (!s.ok()) return RpcFail(s, a.coordinator);
  const double now = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  if (a.json) {
    nlohmann::json arr = nlohmann::json::array();
    for (const auto& w : rep.workers())
      arr.push_back({{"name", w.name()}, {"last_seen", w.last_seen()}, {"leases", w.leases()}, {"items_done", w.items_done()}});
    std::cout << arr.dump(1) << "\n";
    return 0;
  }
  std::printf("%-32s %8s %10s %12s\n", "worker", "leases", "items", "last seen");
  for (const auto& w : rep.workers())
    std::printf("%-32s %8d %10ld %10.1fs ago\n", w.name().c_str(), w.leases(), static_cast<long>(w.items_done()), now - w.last_seen());
  return 0;
}

}  // namespace

void AddRemoteCommands(CLI::App& app, int* exit_code) {
  auto add = [&](const char* name, const char* help, const char* target_help, int (*fn)(const RemoteArgs&), bool watch) {
    auto a = std::make_shared<RemoteArgs>();
    CLI::App* cmd = app.add_subcommand(name, help);
    if (target_help) cmd->add_option(std::string(name) == "submit" ? "spec" : "id", a->target, target_help)->required();
    cmd->add_option("--coordinator", a->coordinator, "coordinator address")->capture_default_str();
    cmd->add_option("--token-file", a->token_file, "file holding a bearer token (else $BISTABLE_TOKEN)");
    cmd->add_option("--tls-ca", a->tls_ca, "PEM CA certificate to verify a TLS coordinator");
    cmd->add_flag("--json", a->json, "print JSON");
    if (watch) cmd->add_flag("--watch", a->watch, "stream progress until the sweep ends");
    cmd->callback([a, exit_code, fn]() {
      Status st = Prepare(*a);
      *exit_code = st.ok() ? fn(*a) : Fail(st);
    });
  };
  add("submit", "Submit a sweep spec to a coordinator (prints the id)", "sweep spec (TOML)", Submit, false);
  add("status", "State and progress of a sweep on a coordinator", "sweep id (or unique prefix)", StatusCmd, true);
  add("cancel", "Cancel a sweep on a coordinator", "sweep id (or unique prefix)", CancelCmd, false);
  add("workers", "Workers seen by a coordinator", nullptr, WorkersCmd, false);

  auto role = std::make_shared<std::string>("client");
  auto name = std::make_shared<std::string>();
  CLI::App* tok = app.add_subcommand("token", "Mint a bearer token: prints the token and its line for the coordinator's tokens file");
  tok->add_option("--role", *role, "client | worker | admin")->capture_default_str();
  tok->add_option("--name", *name, "a name for the token (shown as the submitter, never the token)");
  tok->callback([role, name, exit_code]() {
    if (*role != "client" && *role != "worker" && *role != "admin") {
      *exit_code = Fail(Status::InvalidArgument("role", "role = '" + *role + "' violates role in {client, worker, admin}"));
      return;
    }
    const std::string t = NewToken();
    std::cout << "token: " << t << "\n" << "tokens-file line: " << *role << " " << Sha256Hex(t) << (name->empty() ? "" : " " + *name) << "\n";
    *exit_code = 0;
  });
}

}  // namespace bistable
