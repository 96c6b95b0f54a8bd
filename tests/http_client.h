// A real HTTP/1.1 client for end-to-end tests (Boost.Beast) and a reader of Prometheus text: what the
// observability and hostile-wire tests scrape the coordinator's and workers' /metrics with.
#ifndef BISTABLE_TESTS_HTTP_CLIENT_H_
#define BISTABLE_TESTS_HTTP_CLIENT_H_

#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

namespace bistable_test {

struct HttpReply {
  int status = 0;
  std::string body, content_type;
};

// One request over a fresh connection to 127.0.0.1:port with these headers (Host among them); status −1 and
// the error in body on failure.
inline HttpReply HttpExchange(int port, const std::string& target, boost::beast::http::verb verb,
                              const std::vector<std::pair<std::string, std::string>>& headers) {
  namespace beast = boost::beast;
  namespace http = beast::http;
  namespace asio = boost::asio;
  asio::io_context io;
  asio::ip::tcp::socket sock(io);
  beast::error_code ec;
  sock.connect(asio::ip::tcp::endpoint(asio::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port)), ec);
  if (ec) return {-1, ec.message(), ""};
  http::request<http::empty_body> req{verb, target, 11};
  for (const auto& [name, value] : headers) req.set(name, value);
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

// One request with the Host header `host` (and an X-Padding header when `extra_header` is given).
inline HttpReply HttpRequest(int port, const std::string& target,
                             boost::beast::http::verb verb = boost::beast::http::verb::get,
                             const std::string& extra_header = "", const std::string& host = "127.0.0.1") {
  std::vector<std::pair<std::string, std::string>> headers = {{"Host", host}};
  if (!extra_header.empty()) headers.push_back({"X-Padding", extra_header});
  return HttpExchange(port, target, verb, headers);
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
