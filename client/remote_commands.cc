// `bistable submit | status | cancel | workers | fetch | health | token`: the client side of the distributed service.
#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>

#include <nlohmann/json.hpp>

#include "base/file.h"
#include "base/limits.h"
#include "base/names.h"
#include "client/cli_common.h"
#include "client/json_out.h"
#include "client/map_source.h"
#include "client/progress.h"
#include "client/remote_commands.h"
#include "client/terms_report.h"
#include "dynamics/cancel.h"
#include "engine/json_shapes.h"
#include "proto/coordinator_client.h"
#include "proto/health.h"
#include "server/auth.h"

namespace bistable {
namespace {

struct RemoteArgs {
  std::string coordinator = "127.0.0.1:50051", target, token_file, tls_ca;
  bool json = false, watch = false, insecure_remote = false;
};

// The client for one command: the token and CA resolved once; errors name the flag.
StatusOr<std::unique_ptr<CoordinatorClient>> Connect(const RemoteArgs& a) {
  auto token = LoadToken(a.token_file);
  if (!token.ok()) return token.status();
  return CoordinatorClient::Connect({a.coordinator, a.tls_ca, *token, a.insecure_remote});
}

int Submit(CoordinatorClient& c, const RemoteArgs& a) {
  auto read = ReadTextFile(a.target, "spec", limits::kMaxSpecBytes);
  if (!read.ok()) return Fail(read.status());
  auto text = InlineTermsReport(*read, a.target);  // the coordinator never reads the user's files
  if (!text.ok()) return Fail(text.status());
  auto rep = c.Submit(*text, a.target);
  if (!rep.ok()) return Fail(rep.status());
  if (a.json) {
    std::cout << DumpJson(SubmittedJson(*rep)) << "\n";
  } else {
    std::cout << rep->id << "\n";
  }
  return kExitOk;
}

int StatusCmd(CoordinatorClient& c, const RemoteArgs& a) {
  if (!a.watch) {
    auto st = c.GetStatus(a.target);
    if (!st.ok()) return Fail(st.status());
    if (a.json)
      std::cout << DumpJson(SweepStatusJson(*st)) << "\n";
    else
      std::printf("%s  %s  %ld/%ld points (%ld reused)  %d workers  %.1f s  %s\n", st->id.c_str(),
                  SweepStateName(st->state), st->items_done, st->items_total, st->items_cached, st->workers,
                  st->seconds, st->file.c_str());
    if (!a.json && !st->error.empty()) std::printf("  error: %s\n", Printable(st->error, 400).c_str());
    return st->state == SweepState::kFailed ? kExitNotDone : kExitOk;
  }
  std::unique_ptr<ProgressBar> bar;
  long base = 0;
  auto last = c.Watch(a.target, [&](const SweepInfo& st) {
    if (a.json) {
      std::cout << DumpJson(SweepStatusJson(st)) << std::endl;
      return true;
    }
    if (!bar) {
      base = st.items_done;
      bar = std::make_unique<ProgressBar>(st.items_total - base, "sweep " + st.id, true);
    }
    bar->Update(st.items_done - base, std::to_string(st.workers) + (st.workers == 1 ? " worker" : " workers"));
    return true;
  });
  if (!last.ok()) return Fail(last.status());
  const SweepInfo& st = *last;
  if (bar) bar->Finish(st.items_done - base, SweepStateName(st.state));
  if (!a.json)
    std::printf("%s %s (%d workers at the end)%s%s\n", st.id.c_str(), SweepStateName(st.state), st.workers,
                st.file.empty() ? "" : ", map: ", st.file.c_str());
  return st.state == SweepState::kDone ? kExitOk : kExitNotDone;
}

int CancelCmd(CoordinatorClient& c, const RemoteArgs& a) {
  if (Status st = c.Cancel(a.target); !st.ok()) return Fail(st);
  if (a.json)
    std::cout << DumpJson(nlohmann::json({{"id", a.target}, {"state", "cancelled"}})) << "\n";
  else
    std::cout << "cancelled " << a.target << "\n";
  return kExitOk;
}

int WorkersCmd(CoordinatorClient& c, const RemoteArgs& a) {
  auto ws = c.Workers();
  if (!ws.ok()) return Fail(ws.status());
  const double now = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  if (a.json) {
    nlohmann::json arr = nlohmann::json::array();
    for (const WorkerInfo& w : *ws) arr.push_back(WorkerJson(w));
    std::cout << DumpJson(arr, 1) << "\n";
    return kExitOk;
  }
  std::printf("%-32s %8s %10s %12s\n", "worker", "leases", "items", "last seen");
  for (const WorkerInfo& w : *ws)
    std::printf("%-32s %8d %10ld %10.1fs ago\n", Printable(w.name, 128).c_str(), w.leases, w.items_done,
                now - w.last_seen);
  return kExitOk;
}

// `bistable fetch ID --out F.h5`: the map file streamed, checksummed, written by temp file + rename.
struct FetchArgs {
  RemoteArgs r;
  std::string out;
};

int FetchCmd(CoordinatorClient& c, const FetchArgs& a) {
  InstallCancelSignalHandlers();  // Ctrl-C: the transfer stops, the temp file is removed
  auto fetched = FetchMapFile(c, a.r.target, a.out);
  RestoreDefaultSignalHandlers();
  if (!fetched.ok()) return Fail(fetched.status());
  if (a.r.json)
    std::cout << DumpJson(*fetched) << "\n";
  else
    std::printf("fetched sweep %s: %s (%llu bytes, sha256 %s)\n", (*fetched)["id"].get<std::string>().c_str(),
                a.out.c_str(), static_cast<unsigned long long>((*fetched)["bytes"].get<uint64_t>()),
                (*fetched)["sha256"].get<std::string>().c_str());
  return kExitOk;
}

// `bistable health`: the grpc.health.v1 answer of a coordinator (or worker --health port).
struct HealthArgs {
  RemoteArgs r;
  std::string service;
  double timeout = 5;
};

int HealthCmd(const HealthArgs& a) {
  if (!(a.timeout > 0 && a.timeout <= 3600))  // NaN fails too
    return Fail(Status::InvalidArgument("timeout",
                                        "timeout = " + std::to_string(a.timeout) + " violates timeout in (0, 3600] s"));
  auto token = LoadToken(a.r.token_file);
  if (!token.ok()) return Fail(token.status());
  auto st = CheckHealth({a.r.coordinator, a.r.tls_ca, *token, a.r.insecure_remote}, a.service, a.timeout);
  if (!st.ok()) return Fail(st.status());
  if (a.r.json)
    std::cout << DumpJson(nlohmann::json({{"address", a.r.coordinator}, {"service", a.service}, {"status", *st}}))
              << "\n";
  else
    std::cout << *st << "\n";
  return *st == "SERVING" ? kExitOk : kExitNotDone;
}

}  // namespace

void AddRemoteCommands(CLI::App& app, int* exit_code) {
  auto add = [&](const char* name, const char* help, const char* target_help,
                 int (*fn)(CoordinatorClient&, const RemoteArgs&), bool watch) {
    auto a = std::make_shared<RemoteArgs>();
    CLI::App* cmd = app.add_subcommand(name, help);
    if (target_help) cmd->add_option(std::string(name) == "submit" ? "spec" : "id", a->target, target_help)->required();
    cmd->add_option("--coordinator", a->coordinator, "coordinator address")->capture_default_str();
    cmd->add_option("--token-file", a->token_file, "file holding a bearer token (else $BISTABLE_TOKEN)");
    cmd->add_option("--tls-ca", a->tls_ca, "PEM CA certificate to verify a TLS coordinator");
    cmd->add_flag("--insecure-remote", a->insecure_remote,
                  "send the token in plaintext to an address that is not loopback (refused otherwise)");
    cmd->add_flag("--json", a->json, "print JSON");
    if (watch) cmd->add_flag("--watch", a->watch, "stream progress until the sweep ends");
    cmd->callback([a, exit_code, fn]() {
      auto client = Connect(*a);
      *exit_code = client.ok() ? fn(**client, *a) : Fail(client.status());
    });
  };
  add("submit", "Submit a sweep spec to a coordinator (prints the id)", "sweep spec (TOML)", Submit, false);
  add("status", "State and progress of a sweep on a coordinator", "sweep id (or unique prefix)", StatusCmd, true);
  add("cancel", "Cancel a sweep on a coordinator", "sweep id (or unique prefix)", CancelCmd, false);
  add("workers", "Workers seen by a coordinator", nullptr, WorkersCmd, false);

  {
    auto a = std::make_shared<FetchArgs>();
    CLI::App* cmd = app.add_subcommand(
        "fetch", "Download a published map file from a coordinator (streamed, SHA-256 checked, written atomically)");
    cmd->add_option("id", a->r.target, "sweep id (or unique prefix)")->required();
    cmd->add_option("--out", a->out,
                    "output file (default: <id>.h5 in the current directory; not '-': the file is checked before it is "
                    "renamed into "
                    "place, which standard output cannot be — ./- names a file '-')");
    cmd->add_option("--coordinator", a->r.coordinator, "coordinator address")->capture_default_str();
    cmd->add_option("--token-file", a->r.token_file, "file holding a bearer token (else $BISTABLE_TOKEN)");
    cmd->add_option("--tls-ca", a->r.tls_ca, "PEM CA certificate to verify a TLS coordinator");
    cmd->add_flag("--insecure-remote", a->r.insecure_remote,
                  "send the token in plaintext to an address that is not loopback (refused otherwise)");
    cmd->add_flag("--json", a->r.json, "print JSON");
    cmd->callback([a, exit_code]() {
      if (Status st = CheckFetchOut(a->out); !st.ok()) {  // before connecting
        *exit_code = Fail(st);
        return;
      }
      auto client = Connect(a->r);
      if (!client.ok()) {
        *exit_code = Fail(client.status());
        return;
      }
      FetchArgs args = *a;
      if (args.out.empty()) {  // the sweep's full id names the file: resolve the prefix first
        auto st = (*client)->GetStatus(a->r.target);
        if (!st.ok()) {
          *exit_code = Fail(st.status());
          return;
        }
        if (st->id.empty() || st->id.find_first_not_of("0123456789abcdef") != std::string::npos) {
          *exit_code = Fail(Status::Internal("the coordinator answered a sweep id that is not hex"));
          return;
        }
        args.out = st->id + ".h5";
      }
      *exit_code = FetchCmd(**client, args);
    });
  }
  {
    auto a = std::make_shared<HealthArgs>();
    CLI::App* cmd = app.add_subcommand(
        "health", "grpc.health.v1 check of a coordinator or a worker's --health port (exit 0 when SERVING)");
    cmd->add_option("--coordinator", a->r.coordinator, "address to check")->capture_default_str();
    cmd->add_option("--service", a->service,
                    "service name ('' = the server; bistable.v1.Coordinator, bistable.v1.Worker)");
    cmd->add_option("--timeout", a->timeout, "seconds")->capture_default_str();
    cmd->add_option("--token-file", a->r.token_file, "file holding a bearer token (else $BISTABLE_TOKEN)");
    cmd->add_option("--tls-ca", a->r.tls_ca, "PEM CA certificate to verify a TLS coordinator");
    cmd->add_flag("--insecure-remote", a->r.insecure_remote,
                  "send the token in plaintext to an address that is not loopback (refused otherwise)");
    cmd->add_flag("--json", a->r.json, "print JSON");
    cmd->callback([a, exit_code]() { *exit_code = HealthCmd(*a); });
  }

  auto role = std::make_shared<std::string>("client");
  auto name = std::make_shared<std::string>();
  CLI::App* tok = app.add_subcommand(
      "token", "Mint a bearer token: prints the token and its line for the coordinator's tokens file");
  tok->add_option("--role", *role, "viewer (read only: status, maps, the dashboard) | client | worker | admin")
      ->capture_default_str();
  tok->add_option("--name", *name, "a name for the token (shown as the submitter, never the token)");
  tok->callback([role, name, exit_code]() {
    if (*role != "viewer" && *role != "client" && *role != "worker" && *role != "admin") {
      *exit_code = Fail(
          Status::InvalidArgument("role", "role = '" + *role + "' violates role in {viewer, client, worker, admin}"));
      return;
    }
    // The coordinator would refuse the line at start: say so now.
    if (Status st = CheckTokenName(*name, "name"); !st.ok()) {
      *exit_code = Fail(st);
      return;
    }
    const std::string t = NewToken();
    std::cout << "token: " << t << "\n"
              << "tokens-file line: " << *role << " " << Sha256Hex(t) << (name->empty() ? "" : " " + *name) << "\n";
    *exit_code = 0;
  });
}

}  // namespace bistable
