// The project's one HTTP server (Boost.Beast on Boost.Asio): Prometheus metrics, health and the
// dashboard (server/dashboard.h). GET and HEAD only, routes by exact path (the query string is handed to
// the handler); everything a client sends is bounded (8 KiB of request header, no body, 10 s per request,
// at most 64 connections at once), so a scraper that stalls or a hostile peer costs a socket, not a
// thread. Plaintext, or TLS (Boost.Asio ssl: the PEM certificate and key the gRPC side takes).
#ifndef BISTABLE_NET_HTTP_SERVER_H_
#define BISTABLE_NET_HTTP_SERVER_H_

#include <functional>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "base/status.h"

namespace bistable {

// What a handler sees of a request: the path, the raw query string (after '?', not decoded: see
// ParseQueryString) and the headers a handler may act on. Everything is within the header bound.
struct HttpRequest {
  std::string path, query;
  std::string authorization;  // the Authorization header, "" when absent
  std::string cookie;         // the Cookie header, "" when absent
  std::string host;           // the Host header, "" when absent (HTTP/1.0); see HostAllowed
  std::string peer;           // the peer's IP address
  bool tls = false;           // the connection is TLS (cookies are then marked Secure)
};

struct HttpResponse {
  int status = 200;
  std::string content_type = "text/plain; charset=utf-8";
  std::string body;
  std::vector<std::pair<std::string, std::string>> headers{};  // extra headers (e.g. Set-Cookie)
};
using HttpHandler = std::function<HttpResponse(const HttpRequest&)>;

class HttpServer {
 public:
  struct Options {
    std::string tls_cert_pem, tls_key_pem;  // both set: serve HTTPS only
    // Routes whose handlers may take long (a dashboard map reads a file): they run on a pool of
    // kSlowThreads threads, so that the others (/healthz, /metrics) keep answering meanwhile. At most
    // 4 · kSlowThreads wait or run at once; more get 503 with Retry-After: 1.
    std::set<std::string> slow_routes{};
    // Slow routes whose handlers are heavy (a dashboard cell integrates a point): at most kSlowThreads − 1
    // run at once, so the other slow routes always have a thread; those waiting are served in turn by
    // client (the peer's address with its Authorization header and Cookie), not in arrival order, so one
    // client's flood delays another's request by at most one heavy handler per waiting client. At most
    // kMaxHeavyPerClient of one client wait or run (more: 503 at once, to that client only) and
    // kMaxHeavyPending in all. Each must also be in slow_routes.
    std::set<std::string> heavy_routes{};
  };
  static constexpr int kSlowThreads = 2;
  static constexpr int kMaxHeavyPerClient = 2;
  static constexpr int kMaxHeavyPending = 16;
  // Listens on "host:port" (an IP literal, "localhost" or "[v6]"; port 0 picks a free one) and serves
  // `routes` (path → handler, e.g. "/metrics") on one thread of its own. Handlers run on that thread, but
  // those of Options::slow_routes (which must be safe to call from several threads at once).
  static StatusOr<std::unique_ptr<HttpServer>> Start(const std::string& address,
                                                     std::map<std::string, HttpHandler> routes, const Options& options);
  static StatusOr<std::unique_ptr<HttpServer>> Start(const std::string& address,
                                                     std::map<std::string, HttpHandler> routes) {
    return Start(address, std::move(routes), Options{});
  }
  ~HttpServer();  // stops: closes the listener and every connection, joins the thread and waits for the slow
                  // handlers that are running (those still queued are dropped)
  int port() const;
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  struct Impl;

 private:
  explicit HttpServer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// "a=1&b=x%20y" → {a: "1", b: "x y"} ('+' is a space). InvalidArgument for a malformed escape, a
// repeated or empty name, a byte below 0x20 after decoding, or more than `max_params` parameters.
StatusOr<std::map<std::string, std::string>> ParseQueryString(const std::string& query, size_t max_params = 16);

// The Host rule of every listener that serves data without a token: --metrics of the coordinator and the
// worker always, the coordinator's --http and `bistable run --serve` when no tokens are configured. A web
// page elsewhere can point a host name it controls at this machine (DNS rebinding) and then read it as its
// own origin, but its requests carry that name: so a Host that is an IP literal (IPv4, or IPv6 in brackets)
// or "localhost" (any case), each with or without ":port", is answered, and so is one of `allowed_names`
// (any case, any port: --http-allowed-host, e.g. a Kubernetes Service name a scraper uses); any other name,
// a malformed header or none at all is not.
bool HostAllowed(const std::string& host, const std::vector<std::string>& allowed_names);

// `routes` under that rule: every route but /healthz (which carries no data) answers a request whose Host
// fails HostAllowed with 421 and a fixed JSON error that does not echo the header.
std::map<std::string, HttpHandler> HostChecked(std::map<std::string, HttpHandler> routes,
                                               std::vector<std::string> allowed_names);

// A name for --http-allowed-host: 1-253 letters, digits, '-' and '.' (a DNS name, no port, no wildcard);
// InvalidArgument naming `field` otherwise.
Status CheckAllowedHostName(const std::string& name, const std::string& field);

// The value of cookie `name` in a Cookie header ("" when absent).
std::string CookieValue(const std::string& cookie_header, const std::string& name);

}  // namespace bistable

#endif  // BISTABLE_NET_HTTP_SERVER_H_
