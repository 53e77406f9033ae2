#include "citylod/io/hash.hpp"

#include <cstdio>
#include <fstream>
#include <vector>

#include "citylod/io/error.hpp"
#include "citylod/io/file_check.hpp"

namespace citylod::io {

namespace {

std::uint64_t fnv1a(std::uint64_t h, const void* data, std::size_t size) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < size; ++i) {
    h ^= p[i];
    h *= 0x100000001b3ULL;
  }
  return h;
}

std::string hex16(std::uint64_t h) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

}  // namespace

std::string hash_hex(const void* data, std::size_t size, std::uint64_t seed) {
  return hex16(fnv1a(seed, data, size));
}

std::string hash_file(const std::string& path) {
  regular_file_size(path);  // not a FIFO or a device
  std::ifstream f(path, std::ios::binary);
  if (!f) throw IoError(path, "cannot open for hashing");
  std::uint64_t h = 0xcbf29ce484222325ULL;
  std::vector<char> buf(1 << 16);
  while (f) {
    f.read(buf.data(), std::streamsize(buf.size()));
    const auto n = f.gcount();
    if (n <= 0) break;
    h = fnv1a(h, buf.data(), std::size_t(n));
  }
  return hex16(h);
}

}  // namespace citylod::io
