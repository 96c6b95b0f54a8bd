#include "base/address.h"

#include <arpa/inet.h>

#include <algorithm>

namespace bistable {

bool IsLoopbackAddress(const std::string& listen) {
  if (listen.rfind("unix:", 0) == 0) return true;
  std::string host;
  if (!listen.empty() && listen[0] == '[') {
    const size_t close = listen.find(']');
    if (close == std::string::npos || close + 1 >= listen.size() || listen[close + 1] != ':') return false;
    host = listen.substr(1, close - 1);
  } else {
    const size_t colon = listen.rfind(':');
    if (colon == std::string::npos) return false;
    host = listen.substr(0, colon);
    if (host.find(':') != std::string::npos) return false;  // an unbracketed v6 literal: refuse to guess
  }
  if (host == "localhost") return true;
  in_addr v4{};
  if (::inet_pton(AF_INET, host.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6{};
  if (::inet_pton(AF_INET6, host.c_str(), &v6) == 1) {
    static const unsigned char kLoop[16] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1};
    if (std::equal(v6.s6_addr, v6.s6_addr + 16, kLoop)) return true;
    const bool mapped = std::all_of(v6.s6_addr, v6.s6_addr + 10, [](unsigned char b) { return b == 0; }) &&
                        v6.s6_addr[10] == 0xff && v6.s6_addr[11] == 0xff;
    return mapped && v6.s6_addr[12] == 127;
  }
  return false;
}

}  // namespace bistable
