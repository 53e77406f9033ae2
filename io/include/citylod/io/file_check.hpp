// Checks every reader makes before opening an input: a regular file, of a size
// that is known before anything is allocated. A FIFO, a device (/dev/zero) or
// a socket would block or never end.
#pragma once

#include <cstdint>
#include <string>

namespace citylod::io {

/// The size of `path` in bytes. Throws IoError(path, ...): "no such file", "is a
/// directory, not a file", "is not a regular file (a FIFO, a device or a socket)".
std::uint64_t regular_file_size(const std::string& path);

}  // namespace citylod::io
