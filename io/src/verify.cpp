// verify_point_records(): count, bbox and SHA-256 of the decoded point records.
#include "citylod/io/verify.hpp"

#include <algorithm>
#include <cstring>
#include <vector>

#include "readers_internal.hpp"
#include "sha256.hpp"

namespace citylod::io {

PointRecordDigest verify_point_records(const std::string& path, ProgressFn progress, void* user) {
  const Format f = detect_format(path);
  if (f != Format::las && f != Format::laz)
    throw IoError(path, "not a LAS or LAZ file: only LAS/LAZ point records can be verified");
  auto reader = detail::open_las_records(path);
  const FileInfo& info = reader->info();
  PointRecordDigest d;
  d.point_format = info.las_point_format;
  d.record_length = info.las_record_length;
  d.compressed = info.compressed;
  const std::size_t rl = info.las_record_length;
  const std::size_t batch = std::max<std::size_t>(1, (4u << 20) / rl);
  std::vector<unsigned char> buf(batch * rl);
  detail::Sha256 sha;
  std::size_t n;
  while ((n = reader->read_records(buf.data(), batch)) > 0) {
    sha.update(buf.data(), n * rl);
    for (std::size_t i = 0; i < n; ++i) {
      const unsigned char* p = buf.data() + i * rl;
      Vec3d q;
      for (int a = 0; a < 3; ++a) {
        std::int32_t v;
        std::memcpy(&v, p + 4 * a, 4);
        q[a] = v * info.scale[a] + info.offset[a];
      }
      d.bbox.add(q);
    }
    d.count += n;
    if (progress && !progress(reader->progress(), "verifying", user))
      throw IoError(path, "cancelled");
  }
  d.sha256 = sha.hex();
  return d;
}

std::string sha256_hex(const void* data, std::size_t size) {
  detail::Sha256 s;
  s.update(data, size);
  return s.hex();
}

}  // namespace citylod::io
