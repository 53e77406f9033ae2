// LAZ decode speed next to LAS read speed, in points per second:
//   laz_bench [--repeat N] [--only pf1|pf6]
// (--only: just the one-thread decode of that file, e.g. under callgrind).
// Best of N runs, wall time and process CPU time.
// Rows: LAS records read (raw), LAS through PointReader, LAZ decoded on one
// thread (the LazStream alone, records only), LAZ through PointReader (the
// default decode threads). Files: delft/ahn3_cropped_2 (.las/.laz, point
// format 1) and laz/lone-star.copc.laz (point format 6).
#include <chrono>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "citylod/io/reader.hpp"
#include "laz_decoder.hpp"
#include "readers_internal.hpp"

using namespace citylod::io;

namespace {

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
// CPU time of this process (all threads): on a loaded machine the wall time
// also counts the time the process waited for a core.
double cpu_now() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + ts.tv_nsec * 1e-9;
}

std::string data(const char* rel) {
  return std::string(CITYLOD_SHARED_DATA) + "/" + rel;
}

// The LazStream of a file, as the LAS reader builds it.
detail::LazSource laz_source(const std::string& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string s = ss.str();
  auto u16 = [&](std::size_t o) {
    std::uint16_t v;
    std::memcpy(&v, s.data() + o, 2);
    return v;
  };
  auto u32 = [&](std::size_t o) {
    std::uint32_t v;
    std::memcpy(&v, s.data() + o, 4);
    return v;
  };
  FileInfo h = read_header(p);
  detail::LazSource src;
  src.path = p;
  std::size_t pos = u16(94);
  for (std::uint32_t i = 0; i < u32(100); ++i) {
    const std::uint16_t len = u16(pos + 20);
    if (u16(pos + 18) == 22204) src.vlr.assign(s.begin() + pos + 54, s.begin() + pos + 54 + len);
    pos += 54 + len;
  }
  src.point_offset = u32(96);
  src.file_size = src.data_end = s.size();
  src.point_count = h.point_count;
  src.record_length = h.las_record_length;
  src.point_format = h.las_point_format;
  return src;
}

void report(const char* what, const std::string& file, std::uint64_t n, double best,
            double best_cpu) {
  std::printf("%-34s %-28s %9llu pts %8.1f ms %7.2f Mpts/s  (cpu %8.1f ms %7.2f Mpts/s)\n", what,
              file.substr(file.rfind('/') + 1).c_str(), static_cast<unsigned long long>(n),
              best * 1e3, n / best / 1e6, best_cpu * 1e3, n / best_cpu / 1e6);
}

template <typename Fn>
void bench(const char* what, const std::string& file, int repeat, Fn fn) {
  double best = 1e30, best_cpu = 1e30;
  std::uint64_t n = 0;
  for (int r = 0; r < repeat; ++r) {
    const double t0 = now(), c0 = cpu_now();
    n = fn();
    best = std::min(best, now() - t0);
    best_cpu = std::min(best_cpu, cpu_now() - c0);
  }
  report(what, file, n, best, best_cpu);
}

std::uint64_t read_records(const std::string& p) {
  auto r = detail::open_las_records(p);
  std::vector<unsigned char> buf(65536 * r->info().las_record_length);
  std::uint64_t n = 0, k;
  while ((k = r->read_records(buf.data(), 65536)) > 0) n += k;
  return n;
}

std::uint64_t read_points_api(const std::string& p) {
  auto r = PointReader::open(p);
  PointSet b;
  std::uint64_t n = 0, k;
  while ((k = r->read(b, 1 << 16)) > 0) n += k;
  return n;
}

// The header and VLRs are read before the clock starts: this times decoding.
std::uint64_t decode_single(const detail::LazSource& src) {
  detail::LazStream s(src, 1);
  std::vector<unsigned char> buf(65536 * src.record_length);
  std::uint64_t n = 0, k;
  while ((k = s.read(buf.data(), 65536)) > 0) n += k;
  return n;
}

}  // namespace

int main(int argc, char** argv) {
  int repeat = 5;
  std::string only;
  for (int i = 1; i + 1 < argc; ++i) {
    if (std::string(argv[i]) == "--repeat") repeat = std::max(1, std::atoi(argv[i + 1]));
    if (std::string(argv[i]) == "--only") only = argv[i + 1];
  }
  const std::string las = data("delft/ahn3_cropped_2.las"), laz = data("delft/ahn3_cropped_2.laz");
  const std::string copc = data("laz/lone-star.copc.laz");
  try {
    if (only == "pf1" || only == "pf6") {
      const std::string& f = only == "pf1" ? laz : copc;
      const detail::LazSource src = laz_source(f);
      bench(only == "pf1" ? "LAZ pf1 decode, 1 thread" : "COPC pf6 decode, 1 thread", f, repeat,
            [&] { return decode_single(src); });
      return 0;
    }
    bench("LAS records (raw)", las, repeat, [&] { return read_records(las); });
    bench("LAS PointReader", las, repeat, [&] { return read_points_api(las); });
    const detail::LazSource laz_src = laz_source(laz), copc_src = laz_source(copc);
    bench("LAZ pf1 decode, 1 thread", laz, repeat, [&] { return decode_single(laz_src); });
    bench("LAZ pf1 PointReader (default thr)", laz, repeat, [&] { return read_points_api(laz); });
    bench("COPC pf6 decode, 1 thread", copc, repeat, [&] { return decode_single(copc_src); });
    bench("COPC pf6 PointReader (default thr)", copc, repeat,
          [&] { return read_points_api(copc); });
  } catch (const std::exception& e) {
    std::fprintf(stderr, "laz_bench: %s\n", e.what());
    return 1;
  }
  std::printf("decode threads by default: %d (CITYLOD_LAZ_THREADS to change)\n",
              detail::default_laz_threads());
  return 0;
}
