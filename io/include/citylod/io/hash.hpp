// Content hashes (64-bit FNV-1a as 16 hex digits): chunk files, resume keys,
// tileset files compared by `citylod rebuild`.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace citylod::io {

/// 64-bit FNV-1a of bytes, as 16 hex digits.
std::string hash_hex(const void* data, std::size_t size,
                     std::uint64_t seed = 0xcbf29ce484222325ULL);
/// Of a file's content; throws IoError when it cannot be read.
std::string hash_file(const std::string& path);

}  // namespace citylod::io
