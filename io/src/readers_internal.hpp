// Private: the concrete readers behind PointReader::open() and read_mesh().
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "citylod/io/reader.hpp"
#include "input_file.hpp"

namespace citylod::io::detail {

/// Common base of the format readers.
class ReaderBase : public PointReader {
 public:
  /// After read() returned 0: reads and validates what follows the points
  /// (faces: index range; trailing data) and completes info().face_count.
  virtual void check_tail() {}
  /// The next up to `max_faces` faces (polygons, 0-based indices, validated against the
  /// vertex count) into `out` (cleared first; null: validated only), after the rest of the
  /// points. Returns how many; 0 at the end (the data behind the faces then checked).
  /// Throws if the file has no faces.
  virtual std::size_t read_faces(FaceBatch* out, std::size_t max_faces);
  /// Every face (read_faces() to the end), appended to `faces`.
  void read_all_faces(std::vector<std::vector<std::uint32_t>>& faces);
  FileInfo& mutable_info() { return info_; }
};

/// LAS and LAZ: also hands out the raw point records.
class LasRecordReader : public ReaderBase {
 public:
  /// Copies the next up to n point records, in LAS record layout
  /// (info().las_record_length bytes each; LAZ decoded), into dst. Returns how
  /// many; 0 at the end. Advances points_read() like read().
  virtual std::size_t read_records(unsigned char* dst, std::size_t n) = 0;
};
std::unique_ptr<LasRecordReader> open_las_records(const std::string& path);

std::unique_ptr<ReaderBase> open_ply(const std::string& path);
std::unique_ptr<ReaderBase> open_off(const std::string& path);
std::unique_ptr<ReaderBase> open_obj(const std::string& path);
std::unique_ptr<ReaderBase> open_xyz(const std::string& path);
std::unique_ptr<ReaderBase> open_las(const std::string& path);  // LAS and LAZ
std::unique_ptr<ReaderBase> open_reader(const std::string& path);
/// ... of a format detect_format(path) gave (the file is not sniffed again).
std::unique_ptr<ReaderBase> open_reader(const std::string& path, Format f);

/// OBJ meshes are read in one pass (vn are referenced by faces, not by vertices).
void read_obj_mesh(const std::string& path, PolygonMesh& mesh, std::vector<Vec3f>& normals);

/// The faces of an OBJ file, streamed (a second pass over the file, after its vertices:
/// `vertex_count` of them). Relative indices count the "v" lines before their face.
class ObjFaceStream {
 public:
  ObjFaceStream(const std::string& path, std::uint64_t vertex_count);
  /// Clears `out` and fills it with up to `max_faces` next faces; 0 at the end.
  std::size_t read(FaceBatch& out, std::size_t max_faces);

 private:
  InputFile in_;
  std::uint64_t total_ = 0, seen_ = 0, faces_ = 0, line_no_ = 0;
  std::string line_;
  std::vector<std::string_view> tok_;
};

/// Error text for an out-of-range face index.
std::string bad_index_message(std::uint64_t face, std::int64_t index, std::uint64_t vertex_count);

/// Scales a colour channel to 8 bits: integers 0..255 stay; 0..1 floats are scaled.
std::uint8_t color_to_u8(double v, bool is_float);

}  // namespace citylod::io::detail
