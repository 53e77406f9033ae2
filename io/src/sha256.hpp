// Private: a small streaming SHA-256 (FIPS 180-4), for record digests.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace citylod::io::detail {

class Sha256 {
 public:
  Sha256();
  void update(const void* data, std::size_t size);
  /// Finishes and returns the digest as lower-case hex (the object is spent).
  std::string hex();

 private:
  void block(const unsigned char* p);

  std::uint32_t h_[8];
  unsigned char buf_[64];
  std::size_t used_ = 0;
  std::uint64_t bytes_ = 0;
};

}  // namespace citylod::io::detail
