// A real HTTP/1.1 client for end-to-end tests (Boost.Beast) and a reader of Prometheus text: what the
// observability and hostile-wire tests scrape the coordinator's and workers' /metrics with.
#ifndef BISTABLE_TESTS_HTTP_CLIENT_H_
#define BISTABLE_TESTS_HTTP_CLIENT_H_

#include <map>
#include <sstream>
#include <string>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

namespace bistable_test {

struct HttpReply {
  int status = 0;
  std::string body, content_type;
};

// One request over a fresh connection to 127.0.0.1:port, with the Host header `host`; status −1 and the
// error in body on failure.
inline HttpReply HttpRequest(int port, const std::string& target,
                             boost::beast::http::verb verb = boost::beast::http::verb::get,
                             const std::string& extra_header = "", const std::string& host = "127.0.0.1") {
  namespace beast = boost::beast;
  namespace http = beast::http;
  namespace asio = boost::asio;
  asio::io_context io;
  asio::ip::tcp::socket sock(io);
  beast::error_code ec;
  sock.connect(asio::ip::tcp::endpoint(asio::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port)), ec);
  if (ec) return {-1, ec.message(), ""};
  http::request<http::empty_body> req{verb, target, 11};
  req.set(http::field::host, host);
  if (!extra_header.empty()) req.set("X-Padding", extra_header);
  http::write(sock, req, ec);
  if (ec) return {-1, ec.message(), ""};
  beast::flat_buffer buf;
  http::response_parser<http::string_body> parser;
  parser.body_limit(64 << 20);
  if (verb == http::verb::head) parser.skip(true);
  http::read(sock, buf, parser, ec);
  if (ec) return {-1, ec.message(), ""};
  const auto& res = parser.get();
  return {static_cast<int>(res.result_int()), res.body(), std::string(res[http::field::content_type])};
}

// Prometheus text → {"name{labels}": value}.
inline std::map<std::string, double> ParseMetrics(const std::string& text) {
  std::map<std::string, double> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    const size_t sp = line.rfind(' ');
    out[line.substr(0, sp)] = std::stod(line.substr(sp + 1));
  }
  return out;
}

}  // namespace bistable_test

#endif  // BISTABLE_TESTS_HTTP_CLIENT_H_
