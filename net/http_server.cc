#include "net/http_server.h"

#include <algorithm>
#include <atomic>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>
#include <type_traits>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/asio/strand.hpp>
#include <boost/asio/thread_pool.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>

#include "base/names.h"

namespace bistable {

namespace beast = boost::beast;
namespace http = beast::http;
namespace asio = boost::asio;
using tcp = asio::ip::tcp;

namespace {

constexpr size_t kMaxHeaderBytes = 8 * 1024;
constexpr int kMaxConnections = 64;
constexpr auto kRequestTimeout = std::chrono::seconds(10);
constexpr int kMaxSlowPending = 4 * HttpServer::kSlowThreads;  // slow requests queued or running at once

// A slow request's work on the pool: its handler, then `finished` (counts down the bounds), then its answer.
using SlowWork = std::function<void(const std::function<void()>& finished)>;

}  // namespace

struct HttpServer::Impl {
  // Declared before io: sessions destroyed with the io_context's pending handlers still count down.
  std::atomic<int> connections{0};
  std::map<std::string, HttpHandler> routes;
  std::set<std::string> slow_routes;
  std::atomic<int> slow_pending{0};         // slow requests queued or running
  std::unique_ptr<asio::ssl::context> tls;  // set: every connection is TLS
  asio::io_context io{1};
  tcp::acceptor acceptor{io};
  std::thread thread;
  // Declared after io: destroyed (joined) first, so no slow handler posts its answer to a destroyed io.
  asio::thread_pool slow{HttpServer::kSlowThreads};
  int port = 0;
  // Heavy slow requests (Options::heavy_routes), declared after the pool: what waits is destroyed first.
  std::set<std::string> heavy_routes;
  std::mutex heavy_mu;
  std::map<std::string, std::deque<SlowWork>> heavy_waiting;  // by client, in arrival order
  std::deque<std::string> heavy_turns;                        // clients with waiting requests, in turn
  std::map<std::string, int> heavy_held;                      // by client: waiting or running
  int heavy_running = 0, heavy_pending = 0;

  void Accept();
  // Queues `work` (a heavy request of `client`) to run in its turn; false, with why, when the client's or
  // the server's bound is reached.
  bool QueueHeavy(const std::string& client, SlowWork work, std::string* why);
  void StartHeavyLocked();  // under heavy_mu: starts waiting requests, one client after another, while a thread is free
                            // to them
};

bool HttpServer::Impl::QueueHeavy(const std::string& client, SlowWork work, std::string* why) {
  std::lock_guard<std::mutex> lock(heavy_mu);
  const auto held = heavy_held.find(client);
  if (held != heavy_held.end() && held->second >= HttpServer::kMaxHeavyPerClient) {
    *why = "busy: " + std::to_string(held->second) +
           " requests of this client to slow routes are running or waiting (at most " +
           std::to_string(HttpServer::kMaxHeavyPerClient) + " per client); retry when one has answered\n";
    return false;
  }
  if (heavy_pending >= HttpServer::kMaxHeavyPending) {
    *why = "busy: " + std::to_string(heavy_pending) +
           " heavy requests are running or waiting, the most this server holds; retry\n";
    return false;
  }
  ++heavy_held[client];
  ++heavy_pending;
  auto& waiting = heavy_waiting[client];
  if (waiting.empty()) heavy_turns.push_back(client);
  waiting.push_back(std::move(work));
  StartHeavyLocked();
  return true;
}

void HttpServer::Impl::StartHeavyLocked() {
  while (heavy_running < HttpServer::kSlowThreads - 1 && !heavy_turns.empty()) {
    const std::string client = std::move(heavy_turns.front());
    heavy_turns.pop_front();
    const auto it = heavy_waiting.find(client);
    SlowWork work = std::move(it->second.front());
    it->second.pop_front();
    if (it->second.empty())
      heavy_waiting.erase(it);
    else
      heavy_turns.push_back(client);  // its next request waits for the other clients' turns
    ++heavy_running;
    asio::post(slow, [this, client, work = std::move(work)]() mutable {
      work([&] {
        std::lock_guard<std::mutex> lock(heavy_mu);
        --heavy_running;
        --heavy_pending;
        if (--heavy_held[client] <= 0) heavy_held.erase(client);
        StartHeavyLocked();
      });
    });
  }
}

namespace {

// One connection: plaintext (beast::tcp_stream) or TLS (beast::ssl_stream over it).
template <class Stream>
class Session : public std::enable_shared_from_this<Session<Stream>> {
 public:
  template <class... Args>
  Session(HttpServer::Impl* server, Args&&... args) : stream_(std::forward<Args>(args)...), server_(server) {
    ++server_->connections;
  }
  ~Session() { --server_->connections; }

  void Start() {
    if constexpr (kTls) {
      beast::get_lowest_layer(stream_).expires_after(kRequestTimeout);
      stream_.async_handshake(asio::ssl::stream_base::server, [self = this->shared_from_this()](beast::error_code ec) {
        if (!ec) self->Read();
      });
    } else {
      Read();
    }
  }

 private:
  static constexpr bool kTls = !std::is_same_v<Stream, beast::tcp_stream>;

  void Read() {
    parser_.emplace();
    parser_->header_limit(kMaxHeaderBytes);
    parser_->body_limit(0);
    beast::get_lowest_layer(stream_).expires_after(kRequestTimeout);
    http::async_read(stream_, buffer_, *parser_,
                     [self = this->shared_from_this()](beast::error_code ec, size_t) { self->OnRead(ec); });
  }

  void Close() {
    beast::error_code ec;
    beast::get_lowest_layer(stream_).socket().shutdown(tcp::socket::shutdown_both, ec);
  }

  void OnRead(beast::error_code ec) {
    if (ec == http::error::end_of_stream) {
      Close();
      return;
    }
    if (ec) {  // timeout, oversized header, a body, garbage: answer 400 when we can, then close
      if (ec == http::error::header_limit || ec == http::error::body_limit || ec == http::error::bad_method ||
          ec == http::error::bad_target || ec == http::error::bad_version)
        Send(Make(400, "bad request\n", http::verb::get, 11, false));
      return;
    }
    const auto& req = parser_->get();
    if (req.method() != http::verb::get && req.method() != http::verb::head) {
      auto res = Make(405, "method not allowed\n", req.method(), req.version(), false);
      res.set(http::field::allow, "GET, HEAD");
      Send(std::move(res));
      return;
    }
    HttpRequest request;
    request.path = std::string(req.target());
    if (auto q = request.path.find('?'); q != std::string::npos) {
      request.query = request.path.substr(q + 1);
      request.path.resize(q);
    }
    request.authorization = std::string(req[http::field::authorization]);
    request.cookie = std::string(req[http::field::cookie]);
    request.host = std::string(req[http::field::host]);
    request.tls = kTls;
    beast::error_code peer_ec;
    const auto peer = beast::get_lowest_layer(stream_).socket().remote_endpoint(peer_ec);
    if (!peer_ec) request.peer = peer.address().to_string();
    auto it = server_->routes.find(request.path);
    if (it == server_->routes.end()) {
      Send(Make(404, "not found\n", req.method(), req.version(), req.keep_alive()));
      return;
    }
    const HttpHandler* handler = &it->second;
    if (!server_->slow_routes.count(request.path)) {
      Respond(Call(*handler, request), req.method(), req.version(), req.keep_alive());
      return;
    }
    // A slow route: computed on the pool, answered on this connection's strand.
    const std::string client = request.peer + "\n" + request.authorization + "\n" + request.cookie;  // in memory only
    const bool heavy = server_->heavy_routes.count(request.path) > 0;
    // Runs the handler, then `finished` (the bounds count down), then posts the answer.
    SlowWork work = [self = this->shared_from_this(), handler, request = std::move(request), method = req.method(),
                     version = req.version(),
                     keep_alive = req.keep_alive()](const std::function<void()>& finished) mutable {
      HttpResponse r = Call(*handler, request);
      finished();
      // The session's last reference goes with the answer onto its strand (it is destroyed there).
      auto& strand = self->stream_;
      asio::post(strand.get_executor(),
                 [self = std::move(self), r = std::move(r), method, version, keep_alive]() mutable {
                   self->Respond(std::move(r), method, version, keep_alive);
                 });
    };
    auto busy = [&](std::string why) {
      Respond(HttpResponse{503, "text/plain; charset=utf-8", std::move(why), {{"Retry-After", "1"}}}, req.method(),
              req.version(), req.keep_alive());
    };
    if (heavy) {  // in turn by client, at most kSlowThreads - 1 at once
      std::string why;
      if (!server_->QueueHeavy(client, std::move(work), &why)) busy(std::move(why));
      return;
    }
    // At most kMaxSlowPending wait or run; more are answered 503 at once here, so that a flood of them cannot
    // hold every connection slot (and with them /healthz) for as long as the pool needs to work through it.
    if (server_->slow_pending.fetch_add(1) >= kMaxSlowPending) {
      --server_->slow_pending;
      busy("busy: too many slow requests at once, retry\n");
      return;
    }
    asio::post(server_->slow,
               [server = server_, work = std::move(work)]() mutable { work([server] { --server->slow_pending; }); });
  }

  static HttpResponse Call(const HttpHandler& handler, const HttpRequest& request) {
    try {
      return handler(request);
    } catch (...) {  // on the pool an escaping exception would end the process
      return {500, "text/plain; charset=utf-8", "internal error\n", {}};
    }
  }

  void Respond(HttpResponse r, http::verb method, unsigned version, bool keep_alive) {
    auto res = Make(r.status, std::move(r.body), method, version, keep_alive);
    res.set(http::field::content_type, r.content_type);
    for (const auto& [name, value] : r.headers) res.insert(name, value);
    Send(std::move(res));
  }

  static http::response<http::string_body> Make(int status, std::string body, http::verb method, unsigned version,
                                                bool keep_alive) {
    http::response<http::string_body> res{static_cast<http::status>(status), version};
    res.set(http::field::server, "bistable");
    res.set(http::field::content_type, "text/plain; charset=utf-8");
    res.set(http::field::cache_control, "no-store");
    res.set("X-Content-Type-Options", "nosniff");
    res.keep_alive(keep_alive);
    const size_t n = body.size();
    if (method != http::verb::head) res.body() = std::move(body);
    res.content_length(n);
    return res;
  }

  void Send(http::response<http::string_body> res) {
    auto sp = std::make_shared<http::response<http::string_body>>(std::move(res));
    beast::get_lowest_layer(stream_).expires_after(kRequestTimeout);
    http::async_write(stream_, *sp, [self = this->shared_from_this(), sp](beast::error_code ec, size_t) {
      if (ec) return;
      if (!sp->keep_alive()) {
        self->Close();
        return;
      }
      self->Read();
    });
  }

  Stream stream_;
  beast::flat_buffer buffer_{kMaxHeaderBytes};
  std::optional<http::request_parser<http::empty_body>> parser_;
  HttpServer::Impl* server_;
};

// "host:port" → endpoint; host an IP literal (v6 in brackets) or "localhost".
StatusOr<tcp::endpoint> ParseEndpoint(const std::string& address) {
  const size_t colon = address.rfind(':');
  if (colon == std::string::npos || colon + 1 >= address.size())
    return Status::InvalidArgument("address", "'" + address + "' is not host:port");
  std::string host = address.substr(0, colon);
  const std::string port_text = address.substr(colon + 1);
  if (port_text.size() > 5 || port_text.find_first_not_of("0123456789") != std::string::npos)
    return Status::InvalidArgument("address", "port of '" + address + "' violates port in [0, 65535]");
  const int port = std::stoi(port_text);
  if (port > 65535) return Status::InvalidArgument("address", "port of '" + address + "' violates port in [0, 65535]");
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  if (host == "localhost") host = "127.0.0.1";
  if (host.empty()) host = "0.0.0.0";
  beast::error_code ec;
  const auto ip = asio::ip::make_address(host, ec);
  if (ec) return Status::InvalidArgument("address", "host of '" + address + "' must be an IP address or localhost");
  return tcp::endpoint(ip, static_cast<unsigned short>(port));
}

}  // namespace

void HttpServer::Impl::Accept() {
  acceptor.async_accept(asio::make_strand(io), [this](beast::error_code ec, tcp::socket socket) {
    if (ec == asio::error::operation_aborted) return;
    if (!ec) {
      if (connections.load() >= kMaxConnections) {
        socket.close(ec);  // over the limit: refuse by closing
      } else {
        if (tls)
          std::make_shared<Session<beast::ssl_stream<beast::tcp_stream>>>(this, std::move(socket), *tls)->Start();
        else
          std::make_shared<Session<beast::tcp_stream>>(this, std::move(socket))->Start();
      }
    }
    Accept();
  });
}

HttpServer::HttpServer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

HttpServer::~HttpServer() {
  asio::post(impl_->io, [impl = impl_.get()] {
    beast::error_code ec;
    impl->acceptor.close(ec);
  });
  impl_->io.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
  impl_->slow.stop();  // queued slow requests are dropped; the running ones finish (their answers go nowhere)
  impl_->slow.join();
  std::lock_guard<std::mutex> lock(impl_->heavy_mu);
  impl_->heavy_waiting.clear();  // waiting heavy requests are dropped too (their connections close unanswered)
}

int HttpServer::port() const { return impl_->port; }

StatusOr<std::unique_ptr<HttpServer>> HttpServer::Start(const std::string& address,
                                                        std::map<std::string, HttpHandler> routes,
                                                        const Options& options) {
  auto ep = ParseEndpoint(address);
  if (!ep.ok()) return ep.status();
  auto impl = std::make_unique<Impl>();
  impl->routes = std::move(routes);
  impl->slow_routes = options.slow_routes;
  impl->heavy_routes = options.heavy_routes;
  beast::error_code ec;
  if (options.tls_cert_pem.empty() != options.tls_key_pem.empty())
    return Status::InvalidArgument("tls", "a TLS certificate and its key go together");
  if (!options.tls_cert_pem.empty()) {
    impl->tls = std::make_unique<asio::ssl::context>(asio::ssl::context::tls_server);
    impl->tls->set_options(asio::ssl::context::default_workarounds | asio::ssl::context::no_sslv2 |
                           asio::ssl::context::no_sslv3 | asio::ssl::context::no_tlsv1 |
                           asio::ssl::context::no_tlsv1_1);
    impl->tls->use_certificate_chain(asio::buffer(options.tls_cert_pem), ec);
    if (!ec) impl->tls->use_private_key(asio::buffer(options.tls_key_pem), asio::ssl::context::pem, ec);
    if (ec) return Status::InvalidArgument("tls", "cannot use the TLS certificate and key: " + ec.message());
  }
  impl->acceptor.open(ep->protocol(), ec);
  if (!ec) impl->acceptor.set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) impl->acceptor.bind(*ep, ec);
  if (!ec) impl->acceptor.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) return Status::IoError("address", "cannot listen on " + address + ": " + ec.message());
  impl->port = impl->acceptor.local_endpoint().port();
  impl->Accept();
  Impl* raw = impl.get();
  impl->thread = std::thread([raw] { raw->io.run(); });
  return std::unique_ptr<HttpServer>(new HttpServer(std::move(impl)));
}

namespace {

int HexDigit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

StatusOr<std::string> Unescape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (size_t i = 0; i < s.size(); ++i) {
    char c = s[i];
    if (c == '+') {
      c = ' ';
    } else if (c == '%') {
      const int hi = i + 2 < s.size() ? HexDigit(s[i + 1]) : -1, lo = i + 2 < s.size() ? HexDigit(s[i + 2]) : -1;
      if (hi < 0 || lo < 0) return Status::InvalidArgument("query", "malformed %-escape in the query string");
      c = static_cast<char>(hi * 16 + lo);
      i += 2;
    }
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
      return Status::InvalidArgument("query", "control character in the query string");
    out += c;
  }
  return out;
}

}  // namespace

StatusOr<std::map<std::string, std::string>> ParseQueryString(const std::string& query, size_t max_params) {
  std::map<std::string, std::string> out;
  size_t start = 0;
  while (start <= query.size() && !query.empty()) {
    size_t amp = query.find('&', start);
    if (amp == std::string::npos) amp = query.size();
    const std::string part = query.substr(start, amp - start);
    start = amp + 1;
    if (part.empty()) continue;
    const size_t eq = part.find('=');
    auto name = Unescape(part.substr(0, eq));
    auto value = Unescape(eq == std::string::npos ? "" : part.substr(eq + 1));
    if (!name.ok()) return name.status();
    if (!value.ok()) return value.status();
    if (name->empty()) return Status::InvalidArgument("query", "a query parameter without a name");
    if (out.size() >= max_params)
      return Status::InvalidArgument("query", "more than " + std::to_string(max_params) + " query parameters");
    if (!out.emplace(*name, *value).second)
      return Status::InvalidArgument("query", "query parameter '" + name->substr(0, 32) + "' repeated");
  }
  return out;
}

namespace {

std::string Lower(std::string s) {
  for (char& ch : s) ch = static_cast<char>(ch >= 'A' && ch <= 'Z' ? ch - 'A' + 'a' : ch);
  return s;
}

}  // namespace

bool HostAllowed(const std::string& host, const std::vector<std::string>& allowed_names) {
  // Split "name[:port]" / "[v6][:port]"; the port, when given, is 1-5 digits.
  std::string name = host, port;
  bool bracketed = false;
  if (!name.empty() && name.front() == '[') {
    const size_t close = name.find(']');
    if (close == std::string::npos) return false;
    if (close + 1 < name.size()) {
      if (name[close + 1] != ':') return false;
      port = name.substr(close + 2);
      if (port.empty()) return false;
    }
    name = name.substr(1, close - 1);
    bracketed = true;
  } else if (const size_t colon = name.find(':'); colon != std::string::npos) {
    port = name.substr(colon + 1);
    name.resize(colon);
    if (port.empty()) return false;
  }
  if (port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos || name.empty()) return false;
  beast::error_code ec;
  if (bracketed) {  // an IPv6 literal: no attacker's name
    (void)asio::ip::make_address_v6(name, ec);
    return !ec;
  }
  (void)asio::ip::make_address_v4(name, ec);  // dotted quad only (inet_pton): "127.0.0.1.nip.io" is a name
  if (!ec) return true;
  const std::string lower = Lower(name);
  if (lower == "localhost") return true;
  return std::any_of(allowed_names.begin(), allowed_names.end(),
                     [&](const std::string& a) { return Lower(a) == lower; });
}

std::map<std::string, HttpHandler> HostChecked(std::map<std::string, HttpHandler> routes,
                                               std::vector<std::string> allowed_names) {
  auto allowed = std::make_shared<const std::vector<std::string>>(std::move(allowed_names));
  for (auto& [path, handler] : routes) {
    if (path == "/healthz") continue;  // no data: probes may name the host as they like
    handler = [allowed, handler = std::move(handler)](const HttpRequest& req) {
      if (HostAllowed(req.host, *allowed)) return handler(req);
      // The header is not echoed.
      return HttpResponse{
          421,
          "application/json",
          "{\"error\": \"misdirected request: this server answers a Host that is an IP address, localhost or a name "
          "given with --http-allowed-host\"}",
          {}};
    };
  }
  return routes;
}

Status CheckAllowedHostName(const std::string& name, const std::string& field) {
  if (name.empty() || name.size() > 253 ||
      name.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789-.") != std::string::npos)
    return Status::InvalidArgument(
        field, field + " '" + Printable(name, 64) +
                   "' violates a host name of 1-253 letters, digits, '-' and '.' (no port, no wildcard)");
  return Status::Ok();
}

std::string CookieValue(const std::string& header, const std::string& name) {
  size_t pos = 0;
  while (pos < header.size()) {
    size_t end = header.find(';', pos);
    if (end == std::string::npos) end = header.size();
    size_t b = header.find_first_not_of(' ', pos);
    if (b < end) {
      const size_t eq = header.find('=', b);
      if (eq < end && header.compare(b, eq - b, name) == 0 && eq - b == name.size())
        return header.substr(eq + 1, end - eq - 1);
    }
    pos = end + 1;
  }
  return "";
}

}  // namespace bistable
