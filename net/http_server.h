// The project's one HTTP server (Boost.Beast on Boost.Asio): Prometheus metrics and health today,
// the dashboard later. GET and HEAD only, routes by exact path; everything a client sends is bounded
// (8 KiB of request header, no body, 10 s per request, at most 64 connections at once), so a scraper
// that stalls or a hostile peer costs a socket, not a thread.
#ifndef BISTABLE_NET_HTTP_SERVER_H_
#define BISTABLE_NET_HTTP_SERVER_H_

#include <functional>
#include <map>
#include <memory>
#include <string>

#include "base/status.h"

namespace bistable {

struct HttpResponse {
  int status = 200;
  std::string content_type = "text/plain; charset=utf-8";
  std::string body;
};
using HttpHandler = std::function<HttpResponse()>;

class HttpServer {
 public:
  // Listens on "host:port" (an IP literal, "localhost" or "[v6]"; port 0 picks a free one) and serves
  // `routes` (path → handler, e.g. "/metrics") on one thread of its own. Handlers run on that thread.
  static StatusOr<std::unique_ptr<HttpServer>> Start(const std::string& address, std::map<std::string, HttpHandler> routes);
  ~HttpServer();  // stops: closes the listener and every connection, joins the thread
  int port() const;
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  struct Impl;

 private:
  explicit HttpServer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace bistable

#endif  // BISTABLE_NET_HTTP_SERVER_H_
