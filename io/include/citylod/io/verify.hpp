// Verification of LAS / LAZ point data: decodes every point record and
// summarises it, so that a LAZ (or COPC) file can be checked against its
// uncompressed twin or a published digest.
//
//   auto d = citylod::io::verify_point_records("tile.laz");
//   std::cout << d.count << " points, sha256 " << d.sha256 << "\n";
#pragma once

#include <cstdint>
#include <string>

#include "citylod/io/reader.hpp"
#include "citylod/io/types.hpp"

namespace citylod::io {

struct PointRecordDigest {
  std::uint64_t count = 0;  ///< point records decoded
  BBox3 bbox;               ///< of the decoded coordinates (X * scale + offset)
  /// SHA-256 (lower-case hex) of all point records in LAS record layout
  /// (point_data_record_length bytes each, as the header declares it), file order.
  std::string sha256;
  int point_format = -1;            ///< 0..10 (compression bits cleared)
  std::uint32_t record_length = 0;  ///< bytes per record
  bool compressed = false;          ///< the file is LAZ
};

/// Decodes every point record of a LAS or LAZ file (bounded memory) and
/// returns the count, the bbox and the SHA-256 of the records. Throws IoError
/// on any defect (truncated, corrupt chunk, not LAS/LAZ).
PointRecordDigest verify_point_records(const std::string& path, ProgressFn progress = nullptr,
                                       void* user = nullptr);

/// SHA-256 of a byte string, lower-case hex (used by verify_point_records).
std::string sha256_hex(const void* data, std::size_t size);

}  // namespace citylod::io
