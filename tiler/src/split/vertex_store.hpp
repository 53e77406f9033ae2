// The vertices of one mesh file while the split streams its faces: in memory
// when they fit their budget, else in a file of fixed-size records read back
// through a block cache of that budget (faces reference vertices near each
// other in the file: a cache of a few blocks serves them). The same values
// either way: the split's output does not depend on which.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "citylod/io/types.hpp"

namespace citylod::tiler {

class VertexStore {
 public:
  /// What a vertex carries besides its ENU position.
  struct Layout {
    bool file = false;     ///< the file's own coordinates (polygons are triangulated in them)
    bool normals = false;  ///< per-vertex normal
    bool colors = false;   ///< per-vertex colour
  };
  struct Vertex {
    io::Vec3d pos{}, file{};
    io::Vec3f normal{};
    io::Rgb8 color{};
  };

  /// `count` vertices will be appended; `budget` bytes for them (or for the cache); the
  /// file at `path` is used (created, removed with the store) when they do not fit.
  VertexStore(Layout layout, std::uint64_t count, std::uint64_t budget, std::string path);
  ~VertexStore();
  VertexStore(const VertexStore&) = delete;
  VertexStore& operator=(const VertexStore&) = delete;

  /// Appends `n` vertices (arrays of n; `file`, `normals`, `colors` may be null: zeros).
  void append(const io::Vec3d* pos, const io::Vec3d* file, const io::Vec3f* normals,
              const io::Rgb8* colors, std::size_t n);
  /// Ends the appending (writes what is buffered); then get() may be called.
  void finish() { flush(); }
  Vertex get(std::uint32_t i) const;
  std::uint64_t size() const { return size_; }
  bool paged() const { return fd_ >= 0; }
  /// Bytes of one vertex as stored.
  std::size_t record_bytes() const { return rec_; }

 private:
  void flush();
  void read_block(std::uint64_t block, std::vector<char>& out) const;

  Layout layout_;
  std::size_t rec_ = 0;
  std::uint64_t size_ = 0;
  std::string path_;
  int fd_ = -1;
  // in memory
  std::vector<io::Vec3d> pos_, file_;
  std::vector<io::Vec3f> normals_;
  std::vector<io::Rgb8> colors_;
  // paged: records appended to `out_` and written in blocks; read through `slots_`
  std::vector<char> out_;
  std::uint64_t written_ = 0;                    ///< records in the file
  static constexpr std::uint64_t kBlock = 1024;  ///< records per block
  struct Slot {
    std::int64_t block = -1;
    std::vector<char> data;
  };
  mutable std::vector<Slot> slots_;  ///< direct-mapped: block b in slot b % size
};

}  // namespace citylod::tiler
