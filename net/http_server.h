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
  std::string host;           // the Host header, "" when absent (HTTP/1.0); see IsLoopbackHost
  bool tls = false;           // the connection is TLS (cookies are then marked Secure)
};

struct HttpResponse {
  int status = 200;
  std::string content_type = "text/plain; charset=utf-8";
  std::string body;
  std::vector<std::pair<std::string, std::string>> headers;  // extra headers (e.g. Set-Cookie)
};
using HttpHandler = std::function<HttpResponse(const HttpRequest&)>;

class HttpServer {
 public:
  struct Options {
    std::string tls_cert_pem, tls_key_pem;  // both set: serve HTTPS only
    // Routes whose handlers may take long (a dashboard cell integrates a point): they run on a pool of
    // kSlowThreads threads, so that the others (/healthz, /metrics) keep answering meanwhile. At most
    // 4 · kSlowThreads wait or run at once; more get 503 with Retry-After: 1.
    std::set<std::string> slow_routes;
  };
  static constexpr int kSlowThreads = 2;
  // Listens on "host:port" (an IP literal, "localhost" or "[v6]"; port 0 picks a free one) and serves
  // `routes` (path → handler, e.g. "/metrics") on one thread of its own. Handlers run on that thread, but
  // those of Options::slow_routes (which must be safe to call from several threads at once).
  static StatusOr<std::unique_ptr<HttpServer>> Start(const std::string& address, std::map<std::string, HttpHandler> routes,
                                                     const Options& options);
  static StatusOr<std::unique_ptr<HttpServer>> Start(const std::string& address, std::map<std::string, HttpHandler> routes) {
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

// Whether a Host header names this machine's loopback: localhost (any case), 127.0.0.1 or [::1], with or
// without ":port". A server without tokens answers only such requests, so that a web page elsewhere cannot
// read it through DNS rebinding (its requests carry the attacker's host name).
bool IsLoopbackHost(const std::string& host);

// The value of cookie `name` in a Cookie header ("" when absent).
std::string CookieValue(const std::string& cookie_header, const std::string& name);

}  // namespace bistable

#endif  // BISTABLE_NET_HTTP_SERVER_H_
