#include "net/http_server.h"

#include <atomic>
#include <thread>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/strand.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

namespace bistable {

namespace beast = boost::beast;
namespace http = beast::http;
namespace asio = boost::asio;
using tcp = asio::ip::tcp;

namespace {

constexpr size_t kMaxHeaderBytes = 8 * 1024;
constexpr int kMaxConnections = 64;
constexpr auto kRequestTimeout = std::chrono::seconds(10);

}  // namespace

struct HttpServer::Impl {
  // Declared before io: sessions destroyed with the io_context's pending handlers still count down.
  std::atomic<int> connections{0};
  std::map<std::string, HttpHandler> routes;
  asio::io_context io{1};
  tcp::acceptor acceptor{io};
  std::thread thread;
  int port = 0;

  void Accept();
};

namespace {

class Session : public std::enable_shared_from_this<Session> {
 public:
  Session(tcp::socket socket, HttpServer::Impl* server) : stream_(std::move(socket)), server_(server) {
    ++server_->connections;
  }
  ~Session() { --server_->connections; }

  void Read() {
    parser_.emplace();
    parser_->header_limit(kMaxHeaderBytes);
    parser_->body_limit(0);
    stream_.expires_after(kRequestTimeout);
    http::async_read(stream_, buffer_, *parser_,
                     [self = shared_from_this()](beast::error_code ec, size_t) { self->OnRead(ec); });
  }

 private:
  void OnRead(beast::error_code ec) {
    if (ec == http::error::end_of_stream) {
      stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
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
    std::string path(req.target());
    if (auto q = path.find('?'); q != std::string::npos) path.resize(q);
    auto it = server_->routes.find(path);
    if (it == server_->routes.end()) {
      Send(Make(404, "not found\n", req.method(), req.version(), req.keep_alive()));
      return;
    }
    HttpResponse r;
    try {
      r = it->second();
    } catch (const std::exception& e) {
      r = {500, "text/plain; charset=utf-8", "internal error\n"};
    }
    auto res = Make(r.status, std::move(r.body), req.method(), req.version(), req.keep_alive());
    res.set(http::field::content_type, r.content_type);
    Send(std::move(res));
  }

  static http::response<http::string_body> Make(int status, std::string body, http::verb method, unsigned version,
                                                bool keep_alive) {
    http::response<http::string_body> res{static_cast<http::status>(status), version};
    res.set(http::field::server, "bistable");
    res.set(http::field::content_type, "text/plain; charset=utf-8");
    res.set(http::field::cache_control, "no-store");
    res.keep_alive(keep_alive);
    const size_t n = body.size();
    if (method != http::verb::head) res.body() = std::move(body);
    res.content_length(n);
    return res;
  }

  void Send(http::response<http::string_body> res) {
    auto sp = std::make_shared<http::response<http::string_body>>(std::move(res));
    stream_.expires_after(kRequestTimeout);
    http::async_write(stream_, *sp, [self = shared_from_this(), sp](beast::error_code ec, size_t) {
      if (ec) return;
      if (!sp->keep_alive()) {
        self->stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
        return;
      }
      self->Read();
    });
  }

  beast::tcp_stream stream_;
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
        std::make_shared<Session>(std::move(socket), this)->Read();
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
}

int HttpServer::port() const { return impl_->port; }

StatusOr<std::unique_ptr<HttpServer>> HttpServer::Start(const std::string& address, std::map<std::string, HttpHandler> routes) {
  auto ep = ParseEndpoint(address);
  if (!ep.ok()) return ep.status();
  auto impl = std::make_unique<Impl>();
  impl->routes = std::move(routes);
  beast::error_code ec;
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

}  // namespace bistable
