// SHA-256 (OpenSSL's EVP), whole or streamed: token hashes, and the checksum of map files fetched
// from a coordinator.
#ifndef BISTABLE_BASE_SHA256_H_
#define BISTABLE_BASE_SHA256_H_

#include <memory>
#include <string>
#include <string_view>

namespace bistable {

class Sha256 {
 public:
  Sha256();
  ~Sha256();
  void Update(std::string_view data);
  std::string HexDigest();  // finishes; call once

 private:
  struct Ctx;
  std::unique_ptr<Ctx> ctx_;
};

std::string Sha256Hex(std::string_view data);

}  // namespace bistable

#endif  // BISTABLE_BASE_SHA256_H_
