// libFuzzer harness of one point cloud / mesh reader (CITYLOD_FUZZ_EXT: las, laz,
// ply, obj, off, xyz): the bytes become a file with that extension, streamed
// by scan_file (header checks, every point, faces), read again as points and,
// for mesh formats, as a mesh (whole and through MeshReader in small batches);
// LAS/LAZ records are also verified.
#include <cstdint>
#include <string>

#include "citylod/io/error.hpp"
#include "citylod/io/reader.hpp"
#include "citylod/io/verify.hpp"
#include "fuzz_support.hpp"

#ifndef CITYLOD_FUZZ_EXT
#error "CITYLOD_FUZZ_EXT (las, laz, ply, obj, off, xyz) must be defined"
#endif

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace citylod;
  const std::string ext = CITYLOD_FUZZ_EXT;
  const std::string path = fuzz::write_input("input." + ext, data, size);
  try {
    const io::FileInfo info = io::scan_file(path);
    if (ext == "ply" || ext == "obj" || ext == "off") {
      if (info.has_faces) {
        io::read_mesh(path);
        // streamed as the splitter reads a mesh file: vertices, then faces in batches
        auto m = io::MeshReader::open(path);
        io::PointSet vb;
        while (m->read_vertices(vb, 7) > 0) {
        }
        io::FaceBatch fb;
        while (m->read_faces(fb, 5) > 0) {
        }
      }
    } else {
      io::read_points(path);
    }
    if (ext == "las" || ext == "laz") io::verify_point_records(path);
  } catch (const std::exception& e) {
    fuzz::expect_names_file(e, path);
  }
  return 0;
}
