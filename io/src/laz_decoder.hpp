// Private: streaming decoder of the point data of a LAZ (LASzip) file,
// COPC included. Decodes chunk by chunk (memory: one chunk's compressed
// bytes, plus a few decoded chunks when decoding in parallel).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace citylod::io::detail {

/// What the LAS header and the laszip VLR say about the point data.
struct LazSource {
  std::string path;
  std::vector<unsigned char> vlr;  ///< payload of VLR "laszip encoded" / 22204
  std::uint64_t point_offset = 0;  ///< start of the point data
  std::uint64_t data_end = 0;      ///< first byte after the point data area (EVLRs or file end)
  std::uint64_t file_size = 0;
  std::uint64_t point_count = 0;
  std::uint32_t record_length = 0;  ///< uncompressed record length (LAS header)
  int point_format = 0;
};

class LazStream {
 public:
  /// Validates the VLR against the header, reads the chunk table. `threads`:
  /// chunks decoded in parallel (<= 1: sequentially in the caller's thread).
  /// Throws IoError("<file>: ...").
  LazStream(const LazSource& source, int threads = 1);
  ~LazStream();
  LazStream(const LazStream&) = delete;
  LazStream& operator=(const LazStream&) = delete;

  /// Decodes the next up to n records (LAS record layout, record_length bytes
  /// each) into dst. Returns how many; < n only at the end of the points.
  /// Throws IoError naming the file and the chunk on corrupt data.
  std::size_t read(unsigned char* dst, std::size_t n);

  /// "LASzip 3.4r3, layered chunks (variable size), 15 chunks" (for info).
  std::string description() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Default number of decode threads (CITYLOD_LAZ_THREADS, else up to 4 cores).
int default_laz_threads();

}  // namespace citylod::io::detail
