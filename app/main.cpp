// citylod executable: the command line over citylod::tiler (app/cli.cpp).
#include "cli.hpp"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

int main(int argc, char** argv) {
#if defined(__GLIBC__)
  // The exact geometry (CGAL lazy numbers, GMP) allocates and frees many
  // blocks: with glibc's defaults the heap top is trimmed and large blocks are
  // mapped anew again and again, and the page faults cost ~8 % of a
  // building's LOD time (cgal_building: 29k -> 17k page faults). Up to 64 MB
  // of freed memory per arena is kept for reuse instead.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 64 << 20);
  mallopt(M_TOP_PAD, 16 << 20);
#endif
  return citylod::app::run_cli(argc, argv);
}
