// `citylod split`: georeferenced, out-of-core ingest and building splitting.
// See split.hpp for the passes; this file reads top to bottom in that order.
#include "citylod/tiler/split.hpp"

#include <unistd.h>

#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <locale>
#include <memory>
#include <mutex>
#include <numeric>
#include <optional>
#include <regex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Eigenvalues>

#include "citylod/geo/georef.hpp"
#include "citylod/geo/units.hpp"
#include "citylod/geo/vertical.hpp"
#include "citylod/io/atomic_file.hpp"
#include "citylod/io/error.hpp"
#include "citylod/io/hash.hpp"
#include "citylod/io/reader.hpp"
#include "citylod/io/writers.hpp"
#include "citylod/tiler/threads.hpp"
#include "citylod/tiler/workdir.hpp"
#include "vertex_store.hpp"

namespace citylod::tiler {

namespace fs = std::filesystem;
using io::IoError;
using io::Vec3d;

// ====================================================================== options
std::uint64_t parse_memory_size(const std::string& s) {
  std::size_t used = 0;
  double v = 0;
  try {
    v = std::stod(s, &used);
  } catch (const std::exception&) {
    throw std::invalid_argument("--memory-limit: '" + s + "' is not a size (e.g. 2G, 512M)");
  }
  std::string unit = s.substr(used);
  for (auto& c : unit) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  double mul = 1;
  if (unit.empty() || unit == "B")
    mul = 1;
  else if (unit == "K" || unit == "KB" || unit == "KIB")
    mul = 1024.0;
  else if (unit == "M" || unit == "MB" || unit == "MIB")
    mul = 1024.0 * 1024;
  else if (unit == "G" || unit == "GB" || unit == "GIB")
    mul = 1024.0 * 1024 * 1024;
  else if (unit == "T" || unit == "TB" || unit == "TIB")
    mul = 1024.0 * 1024 * 1024 * 1024;
  else
    throw std::invalid_argument("--memory-limit: unknown unit '" + unit + "' in '" + s + "'");
  if (!(v > 0) || !std::isfinite(v))
    throw std::invalid_argument("--memory-limit: must be positive");
  // 2^64 bytes and more do not fit the count (the conversion would wrap round)
  if (!(v * mul < 18446744073709551616.0))
    throw std::invalid_argument("--memory-limit: '" + s +
                                "' is more than the largest size there is (16E = 2^64 bytes)");
  return static_cast<std::uint64_t>(v * mul);
}

namespace {
/// "X,Y[,Z]" (commas or blanks) -> numbers; nullopt when malformed or not finite.
std::optional<io::Vec3d> parse_triple(const std::string& s) {
  std::string t = s;
  for (auto& c : t)
    if (c == ',') c = ' ';
  std::istringstream in(t);
  in.imbue(std::locale::classic());
  io::Vec3d v{0, 0, 0};
  int n = 0;
  double d;
  while (in >> d) {
    if (n == 3 || !std::isfinite(d)) return std::nullopt;
    v[std::size_t(n++)] = d;
  }
  if (!in.eof() || n < 2) return std::nullopt;
  return v;
}
}  // namespace

void SplitOptions::validate() const {
  auto positive = [](double v, const char* name) {
    if (!(v > 0) || !std::isfinite(v))
      throw std::invalid_argument(std::string(name) + " must be a positive number");
  };
  if (inputs.empty()) throw std::invalid_argument("no input file");
  if (work_dir.empty()) throw std::invalid_argument("--out WORK is required");
  if (!crs.empty() && !origin.empty())
    throw std::invalid_argument(
        "--crs and --origin exclude each other (--origin is for data in a local metric frame)");
  if (!geoid.empty() && geoid != "egm96")
    throw std::invalid_argument("--geoid: only 'egm96' is supported, got '" + geoid + "'");
  if (!geoid.empty() && !origin.empty())
    throw std::invalid_argument(
        "--geoid needs a CRS; with --origin heights are relative to the given ellipsoidal H");
  if (!vertical.empty() && vertical != "auto" && vertical != "ellipsoidal" &&
      vertical != "orthometric")
    throw std::invalid_argument("--vertical: expected auto, ellipsoidal or orthometric, got '" +
                                vertical + "'");
  if (!vertical.empty() && vertical != "auto" && !origin.empty())
    throw std::invalid_argument(
        "--vertical needs a CRS; with --origin heights are relative to the given ellipsoidal H");
  if (!geoid.empty() && vertical == "ellipsoidal")
    throw std::invalid_argument(
        "--geoid egm96 (orthometric heights) contradicts --vertical ellipsoidal");
  if (footprints.empty() && (!footprints_layer.empty() || !footprints_id.empty()))
    throw std::invalid_argument("--footprints-layer / --footprints-id need --footprints");
  if (!offset.empty() && !parse_triple(offset))
    throw std::invalid_argument("--offset: expected X,Y or X,Y,Z (numbers), got '" + offset + "'");
  positive(cell_size, "--cell-size");
  positive(halo, "--halo");
  positive(seg.cluster_tolerance, "--cluster-tolerance");
  positive(seg.dtm_resolution, "dtm resolution");
  if (max_halo < halo) throw std::invalid_argument("--max-halo must be >= --halo");
  if (footprint_buffer < 0) throw std::invalid_argument("--footprint-buffer must be >= 0");
  if (memory_limit < (64ull << 20))
    throw std::invalid_argument("--memory-limit must be at least 64M");
  if (seg.min_height < 0) throw std::invalid_argument("--min-height must be >= 0");
  if (seg.min_area < 0) throw std::invalid_argument("--min-area must be >= 0");
}

std::string SplitOptions::canonical() const {
  std::ostringstream o;
  o.precision(17);
  // a "PG:" connection string's password stays out of the manifest
  static const std::regex pw(R"((password\s*=\s*)('[^']*'|\S+))", std::regex::icase);
  o << "v=3;crs=" << crs << ";origin=" << origin << ";geoid=" << geoid
    << ";footprints=" << std::regex_replace(footprints, pw, "$1***")
    << ";footprint_buffer=" << footprint_buffer << ";memory_limit=" << memory_limit
    << ";cell=" << cell_size << ";halo=" << halo << ";max_halo=" << max_halo
    << ";ignore_classes=" << ignore_classes << ";min_footprint_points=" << min_footprint_points
    << ";dtm_res=" << seg.dtm_resolution << ";dtm_window=" << seg.dtm_window
    << ";ground_tol=" << seg.ground_tolerance << ";min_height=" << seg.min_height
    << ";tol=" << seg.cluster_tolerance << ";min_pts=" << seg.min_cluster_points
    << ";min_area=" << seg.min_area << ";min_bh=" << seg.min_building_height
    << ";k=" << seg.feature_neighbours << ";max_scatter=" << seg.max_scatter
    << ";max_veg=" << seg.max_vegetation_ratio << ";min_planar=" << seg.min_planar_fraction
    << ";min_width=" << seg.min_width << ";low=" << seg.low_height << ","
    << seg.low_max_vegetation_ratio << "," << seg.low_min_planar_fraction;
  // v=2: heights follow the CRS by default (RD New -> NAP); v=1 work directories split again
  o << ";vertical=" << (vertical.empty() ? "auto" : vertical)
    << ";footprints_layer=" << footprints_layer << ";footprints_id=" << footprints_id
    << ";unmatched=" << (unmatched == Unmatched::segment ? "segment" : "drop");
  if (!offset.empty()) o << ";offset=" << offset;
  return o.str();
}

namespace {

// ====================================================================== helpers
std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

/// "<size>:<mtime ns>" of a file; IoError when it does not exist.
std::string fingerprint(const std::string& path) {
  std::error_code ec;
  const auto st = fs::status(path, ec);
  if (ec || !fs::exists(st)) throw IoError(path, "no such file");
  if (fs::is_directory(st)) throw IoError(path, "is a directory, not a point cloud or mesh file");
  const auto size = fs::file_size(path, ec);
  if (ec) throw IoError(path, "cannot stat: " + ec.message());
  const auto mtime = fs::last_write_time(path, ec).time_since_epoch().count();
  return std::to_string(size) + ":" + std::to_string(static_cast<long long>(mtime));
}

std::string sanitize_id(const std::string& s) {
  std::string r;
  for (char c : s)
    r +=
        (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.') ? c : '_';
  if (r.empty() || r[0] == '.') r = "_" + r;
  // a work directory's ids never hold ".." (workdir.cpp refuses them as paths)
  for (std::size_t k = r.find(".."); k != std::string::npos; k = r.find("..")) r[k + 1] = '_';
  return r.substr(0, 120);
}

using CellKey = std::pair<int, int>;
/// The cell of (x, y) in a grid of cells of `size` (cell_ / 2^depth: halving is exact, so
/// a point's quarter cell lies inside its cell).
CellKey key_at(double x, double y, double size) {
  return {static_cast<int>(std::floor(x / size)), static_cast<int>(std::floor(y / size))};
}
struct CellKeyHash {
  std::size_t operator()(const CellKey& k) const {
    // unsigned: shifting a negative cell index is undefined behaviour
    return std::hash<unsigned long long>()(
        (static_cast<unsigned long long>(static_cast<unsigned>(k.first)) << 32) ^
        static_cast<unsigned>(k.second));
  }
};

// One spilled point: 48 bytes.
struct SpillRec {
  double x, y, z;
  float nx, ny, nz;
  std::uint8_t r, g, b, cls;
  std::uint64_t src;  ///< mesh vertex reference (input << 40 | vertex), or kNoSrc
};
static_assert(sizeof(SpillRec) == 48, "spill record layout");
constexpr std::uint64_t kNoSrc = ~0ull;
constexpr double kMeshSamplesPerM2 = 4.0;  ///< triangle samples per m^2 (plus each centroid)

// One spilled mesh triangle (mesh scenes): its corners in ENU with their attributes and
// vertex ids, so that a region, and the chunk writer at the end, need no mesh in memory.
struct FaceRec {
  std::uint64_t id;      ///< input << 40 | triangle
  std::uint64_t vid[3];  ///< input << 40 | vertex
  double v[3][3];        ///< ENU corners
  float n[3][3];         ///< vertex normals (when the input has them)
  std::uint8_t rgb[3][3];
  std::uint8_t pad[3];
};
static_assert(sizeof(FaceRec) == 152, "face record layout");

// A chunk's claim on a triangle: the samples of the triangle among its members.
struct ClaimRec {
  FaceRec face;
  std::uint32_t votes;
  std::uint32_t chunk;  ///< index in the splitter's chunk list
};
static_assert(sizeof(ClaimRec) == 160, "claim record layout");

/// Records of any type appended to per-cell files `<prefix>i_j.bin` through one
/// bounded buffer (sorted by cell when full; the order within a cell is the order of
/// arrival).
template <class Rec>
class CellFiles {
 public:
  CellFiles(fs::path dir, std::string prefix, std::size_t budget_records)
      : dir_(std::move(dir)),
        prefix_(std::move(prefix)),
        budget_(std::max<std::size_t>(budget_records, 1024)) {}
  fs::path file(const CellKey& k) const {
    return dir_ / (prefix_ + std::to_string(k.first) + "_" + std::to_string(k.second) + ".bin");
  }
  void add(const CellKey& k, const Rec& r) {
    if (buf_.capacity() < budget_) buf_.reserve(budget_);  // once: no growth by copies
    buf_.push_back({k, r});
    if (buf_.size() >= budget_) flush();
  }
  /// Writes the buffer out by cell, each cell's records in arrival order (a stable sort
  /// through an index: no sorted or per-cell copy of the buffer, pieces of kPiece).
  void flush() {
    std::vector<std::uint32_t> order(buf_.size());
    std::iota(order.begin(), order.end(), 0u);
    std::sort(order.begin(), order.end(), [this](std::uint32_t a, std::uint32_t b) {
      return buf_[a].first != buf_[b].first ? buf_[a].first < buf_[b].first : a < b;
    });
    constexpr std::size_t kPiece = 4096;
    std::vector<Rec> run;
    run.reserve(std::min(kPiece, order.size()));
    for (std::size_t j = 0; j < order.size();) {
      const CellKey k = buf_[order[j]].first;
      run.clear();
      while (j < order.size() && buf_[order[j]].first == k && run.size() < kPiece)
        run.push_back(buf_[order[j++]].second);
      append(k, run.data(), run.size());
    }
    std::vector<std::pair<CellKey, Rec>>().swap(buf_);
  }
  /// Appends `n` records to the cell's file (unbuffered).
  void append(const CellKey& k, const Rec* recs, std::size_t n) {
    const fs::path p = file(k);
    std::FILE* f = std::fopen(p.c_str(), "ab");
    if (!f)
      throw IoError(p.string(), std::string("cannot open spill file: ") + std::strerror(errno));
    const std::size_t wrote = std::fwrite(recs, sizeof(Rec), n, f);
    const bool ok = std::fclose(f) == 0 && wrote == n;
    if (!ok)
      throw IoError(p.string(), std::string("cannot write spill file: ") + std::strerror(errno));
    counts_[k] += n;
    bytes_ += n * sizeof(Rec);
  }
  /// Calls fn(record) for every record of a cell's file, read in blocks.
  template <class Fn>
  void for_each(const CellKey& k, Fn&& fn) const {
    if (!counts_.count(k)) return;
    const fs::path p = file(k);
    std::FILE* f = std::fopen(p.c_str(), "rb");
    if (!f)
      throw IoError(p.string(), std::string("cannot read spill file: ") + std::strerror(errno));
    std::vector<Rec> buf(2048);
    std::size_t got;
    while ((got = std::fread(buf.data(), sizeof(Rec), buf.size(), f)) > 0)
      for (std::size_t i = 0; i < got; ++i) fn(buf[i]);
    const bool err = std::ferror(f);
    std::fclose(f);
    if (err) throw IoError(p.string(), "cannot read spill file");
  }
  /// Every record of a cell's file (empty when it has none).
  std::vector<Rec> read(const CellKey& k) const {
    std::vector<Rec> out;
    const auto it = counts_.find(k);
    if (it == counts_.end()) return out;
    out.resize(it->second);
    const fs::path p = file(k);
    std::FILE* f = std::fopen(p.c_str(), "rb");
    if (!f)
      throw IoError(p.string(), std::string("cannot read spill file: ") + std::strerror(errno));
    const std::size_t got = std::fread(out.data(), sizeof(Rec), out.size(), f);
    std::fclose(f);
    if (got != out.size()) throw IoError(p.string(), "cannot read spill file (truncated)");
    return out;
  }
  const std::map<CellKey, std::uint64_t>& counts() const { return counts_; }
  std::uint64_t bytes() const { return bytes_; }

 private:
  fs::path dir_;
  std::string prefix_;
  std::size_t budget_;
  std::vector<std::pair<CellKey, Rec>> buf_;
  std::map<CellKey, std::uint64_t> counts_;
  std::uint64_t bytes_ = 0;
};

/// Grid of cells spilled to per-cell files (CellFiles without its buffer). Points
/// collect in a fixed buffer; when it is full it is handed to a writer thread, which
/// sorts it by cell and appends each run to its cell's file while the next buffer fills
/// (two buffers of half the budget; the files' content does not depend on their size).
class Spiller {
 public:
  Spiller(fs::path dir, double cell, std::size_t budget_records)
      : files_(std::move(dir), "", 0),
        cell_(cell),
        budget_(std::max<std::size_t>(budget_records / 2, 4096)) {
    buf_.reserve(budget_);
  }
  ~Spiller() {
    if (writer_.joinable()) writer_.join();
  }
  Spiller(const Spiller&) = delete;
  Spiller& operator=(const Spiller&) = delete;

  CellKey key(double x, double y) const { return key_at(x, y, cell_); }
  fs::path file(const CellKey& k) const { return files_.file(k); }
  void add(const SpillRec& r) {
    buf_.push_back(r);
    if (buf_.size() >= budget_) flush_behind();
  }
  /// Writes what is buffered and waits for the writer: the files are complete.
  void flush() {
    wait_writer();
    write(buf_);
    buf_.clear();
  }
  /// Frees the buffers (after the last flush).
  void release() {
    wait_writer();
    std::vector<SpillRec>().swap(buf_);
    std::vector<SpillRec>().swap(writing_);
  }
  const std::map<CellKey, std::uint64_t>& counts() const { return files_.counts(); }
  std::uint64_t bytes() const { return files_.bytes(); }
  double cell() const { return cell_; }

 private:
  /// The full buffer to the writer thread (after the previous one is written).
  void flush_behind() {
    wait_writer();
    writing_.swap(buf_);
    buf_.clear();
    if (buf_.capacity() < budget_) buf_.reserve(budget_);
    writer_ = std::thread([this] {
      try {
        write(writing_);
      } catch (...) {
        error_ = std::current_exception();
      }
    });
  }
  void wait_writer() {
    if (writer_.joinable()) writer_.join();
    if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
  }
  /// `buf` out by cell, each cell's records in arrival order: the cell of each record
  /// computed once, a counting sort of the records by cell (a scene's buffer meets few
  /// cells), each cell's run written through a piece buffer. (A comparison sort
  /// recomputing both keys per comparison took 20 % of a split.)
  void write(const std::vector<SpillRec>& buf) {
    std::vector<std::uint32_t> cell_of(buf.size());
    std::vector<CellKey> cells;
    std::map<CellKey, std::uint32_t> index;
    CellKey last{};
    std::uint32_t last_i = ~0u;
    for (std::size_t i = 0; i < buf.size(); ++i) {
      const CellKey k = key(buf[i].x, buf[i].y);
      if (last_i == ~0u || k != last) {  // points arrive in runs of one cell
        const auto it = index.emplace(k, std::uint32_t(cells.size())).first;
        if (it->second == cells.size()) cells.push_back(k);
        last = k;
        last_i = it->second;
      }
      cell_of[i] = last_i;
    }
    std::vector<std::size_t> start(cells.size() + 1, 0);
    for (const std::uint32_t c : cell_of) ++start[c + 1];
    for (std::size_t c = 0; c < cells.size(); ++c) start[c + 1] += start[c];
    std::vector<std::uint32_t> order(buf.size());
    {
      std::vector<std::size_t> next(start.begin(), start.end() - 1);
      for (std::size_t i = 0; i < buf.size(); ++i) order[next[cell_of[i]]++] = std::uint32_t(i);
    }
    constexpr std::size_t kPiece = 4096;
    std::vector<SpillRec> run;
    run.reserve(kPiece);
    for (const auto& [k, c] : index)  // cells in key order, as the files were written before
      for (std::size_t j = start[c]; j < start[c + 1];) {
        run.clear();
        while (j < start[c + 1] && run.size() < kPiece) run.push_back(buf[order[j++]]);
        files_.append(k, run.data(), run.size());
      }
  }

  CellFiles<SpillRec> files_;
  double cell_;
  std::size_t budget_;
  std::vector<SpillRec> buf_;      ///< filling
  std::vector<SpillRec> writing_;  ///< being written by writer_
  std::thread writer_;
  std::exception_ptr error_;
};

/// Points of a cell + halo, gathered from the spill files.
struct RegionPoints {
  std::array<double, 4> box{0, 0, 0, 0};  ///< xmin ymin xmax ymax
  std::vector<Vec3d> pos;
  std::vector<io::Vec3f> nrm;
  std::vector<io::Rgb8> rgb;
  std::vector<std::uint8_t> cls;
  std::vector<std::uint64_t> src;
  std::vector<FaceRec> faces;  ///< mesh scenes: the triangles meeting the box, by id
  const FaceRec& face(std::uint64_t id) const {
    const auto it = std::lower_bound(faces.begin(), faces.end(), id,
                                     [](const FaceRec& f, std::uint64_t v) { return f.id < v; });
    if (it == faces.end() || it->id != id) throw std::logic_error("split: region face missing");
    return *it;
  }
};

/// The work directory transaction: a staging dir inside WORK, removed unless committed.
class Staging {
 public:
  explicit Staging(const fs::path& work) : work_(work) {
    created_work_ = !fs::exists(work_);
    std::error_code ec;
    fs::create_directories(work_, ec);
    if (ec) throw IoError(work_.string(), "cannot create work directory: " + ec.message());
    remove_stale();
    dir_ = work_ / (".split.tmp." + std::to_string(::getpid()));
    fs::remove_all(dir_, ec);
    fs::create_directories(dir_ / "spill", ec);
    fs::create_directories(dir_ / "chunks", ec);
    fs::create_directories(dir_ / "faces", ec);
    if (ec) throw IoError(dir_.string(), "cannot create staging directory: " + ec.message());
    // Chunks written in place (no temp file, fsync or rename each), made durable by one
    // syncfs in commit(): a chunk's fsync was 7 % of a replica's split and most of its wait.
    staged_ = std::make_unique<io::StagedDirectory>(dir_.string());
  }
  ~Staging() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
    if (!committed_ && created_work_ && fs::is_empty(work_, ec)) fs::remove(work_, ec);
  }
  Staging(const Staging&) = delete;
  Staging& operator=(const Staging&) = delete;

  fs::path spill() const { return dir_ / "spill"; }
  /// A scratch file of the staging directory (removed with it).
  fs::path scratch(const std::string& name) const { return dir_ / name; }
  fs::path chunks() const { return dir_ / "chunks"; }
  void drop_spill() {
    std::error_code ec;
    fs::remove_all(spill(), ec);
  }
  /// Mesh scenes: face records, chunk claims and won triangles.
  fs::path faces() const { return dir_ / "faces"; }
  void drop_faces() {
    std::error_code ec;
    fs::remove_all(faces(), ec);
  }

  /// Swaps the staged chunks in and writes the manifest; restores the old state on failure.
  void commit(const Manifest& m) {
    const fs::path live = work_ / "chunks";
    const fs::path old = dir_ / "chunks.old";
    io::sync_file_system(chunks().string());
    std::error_code ec;
    const bool had_live = fs::exists(live);
    if (had_live) {
      fs::rename(live, old, ec);
      if (ec) throw IoError(live.string(), "cannot move old chunks aside: " + ec.message());
    }
    fs::rename(chunks(), live, ec);
    if (ec) {
      if (had_live) fs::rename(old, live, ec);
      throw IoError(live.string(), "cannot publish chunks: " + ec.message());
    }
    try {
      write_manifest(work_.string(), m);
    } catch (...) {
      std::error_code e2;
      fs::rename(live, chunks(), e2);
      if (had_live) fs::rename(old, live, e2);
      throw;
    }
    committed_ = true;
  }

 private:
  void remove_stale() {
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(work_, ec)) {
      const std::string name = e.path().filename().string();
      const std::string prefix = ".split.tmp.";
      if (name.rfind(prefix, 0) != 0) continue;
      const long pid = std::strtol(name.c_str() + prefix.size(), nullptr, 10);
      if (pid > 0 && pid != ::getpid() && ::kill(static_cast<pid_t>(pid), 0) == 0)
        throw IoError(work_.string(), "another 'citylod split' (pid " + std::to_string(pid) +
                                          ") is writing this work directory");
      std::error_code e2;
      fs::remove_all(e.path(), e2);
    }
  }

  fs::path work_, dir_;
  std::unique_ptr<io::StagedDirectory> staged_;
  bool created_work_ = false, committed_ = false;
};

/// Progress over weighted stages.
class Stages {
 public:
  explicit Stages(const ProgressFn& fn) : fn_(fn) {}
  void report(double begin, double end, double f, const char* stage) {
    if (!fn_) return;
    report_progress(fn_, "split", begin + (end - begin) * std::clamp(f, 0.0, 1.0), stage);
  }

 private:
  const ProgressFn& fn_;
};

struct InputInfo {
  std::string path;  ///< as given
  std::string abs;   ///< absolute, normalised (recorded in the manifest)
  io::FileInfo info;
  bool mesh = false;
  io::Vec3d offset{0, 0, 0};   ///< added to its coordinates (--offset, or metadata.xml)
  std::string sidecar_crs;     ///< CRS from FILE.prj or metadata.xml <SRS> ("" = none)
  std::string sidecar_origin;  ///< "LAT,LON,0" from a metadata.xml <SRS>ENU:lat,lon
};

std::string crs_spec_of(const io::FileInfo& i) {
  if (!i.crs_wkt.empty()) return i.crs_wkt;
  if (i.epsg)
    return "EPSG:" + std::to_string(i.epsg) +
           (i.vertical_epsg ? "+" + std::to_string(i.vertical_epsg) : "");
  return {};
}

Eigen::AlignedBox3d to_eigen(const io::BBox3& b) {
  return Eigen::AlignedBox3d(Eigen::Vector3d(b.min[0], b.min[1], b.min[2]),
                             Eigen::Vector3d(b.max[0], b.max[1], b.max[2]));
}

std::string inputs_label(const std::vector<InputInfo>& in) {
  std::string s = in.front().path;
  if (in.size() > 1) s += " (+" + std::to_string(in.size() - 1) + " more)";
  return s;
}

/// A chunk being assembled, before the file is written.
struct PendingChunk {
  ChunkRecord rec;
};

/// footprint_of's answer rasters (by 50 m bucket) and the queries of the buckets that
/// have none yet: one per pass-3 worker (the answers do not depend on it).
struct FpCache {
  std::unordered_map<CellKey, std::vector<std::int32_t>, CellKeyHash> raster;
  std::unordered_map<CellKey, std::uint32_t, CellKeyHash> queries;
};

/// What pass 3 makes of one cell, merged into the split in cell order (merge_cell): the
/// chunks' ids, their order, their files and the report do not depend on which worker
/// ran the cell, nor when.
struct CellOutput {
  struct Chunk {
    PendingChunk pc;
    std::string base_id;           ///< before unique_id; "" = from the cluster's centroid
    Vec2 cluster_at{0, 0};         ///< a cluster's centroid (scene frame): its id
    bool write = false;            ///< a point chunk: `points` to WORK/chunks/<id>.ply
    bool unmatched = false;        ///< --unmatched segment: a building without footprint
    io::PointSet points;           ///< chunk coordinates, in the chunk's order
    std::vector<ClaimRec> claims;  ///< mesh scenes (the chunk index set by the merge)
  };
  std::vector<Chunk> chunks;
  SplitReport rep;  ///< this cell's notes, cluster lines and counters
  std::size_t subdivided = 0, fp_few = 0, fp_few_points = 0, fp_few_max = 0;
};

/// Points of the regions the pass-3 workers hold at once, within the region budget: a
/// worker waits before loading a region that does not fit, unless its cell is the
/// oldest unmerged one (which the others wait for, so it never waits itself).
class RegionGate {
 public:
  explicit RegionGate(std::size_t budget) : budget_(budget) {}
  /// Raises the points `held` by cell `index` to `n` (waiting as above).
  void hold(std::size_t index, std::size_t& held, std::size_t n) {
    if (n <= held) return;
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait(lock, [&] { return index <= oldest_ || used_ + (n - held) <= budget_; });
    used_ += n - held;
    held = n;
  }
  /// Cell `index` is merged: its points are freed and the next cell is the oldest.
  void done(std::size_t index, std::size_t& held) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      used_ -= held;
      oldest_ = std::max(oldest_, index + 1);
    }
    held = 0;
    cv_.notify_all();
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  std::size_t budget_, used_ = 0, oldest_ = 0;
};

/// One cell's work in pass 3: its place in the pass's order, the region points it
/// holds through the gate, its worker's footprint cache and what it produces.
struct CellJob {
  std::size_t index = 0;
  std::size_t held = 0;
  RegionGate* gate = nullptr;
  FpCache* fp = nullptr;
  CellOutput out;
};

// ---------------------------------------------------------------------- inputs, sidecars
/// A folder input stands for the scene files under it (any depth, sorted by path).
std::vector<std::string> expand_inputs(const std::vector<std::string>& inputs) {
  static const std::set<std::string> exts{"ply", "obj", "off", "las", "laz", "xyz", "pts"};
  std::vector<std::string> out;
  for (const auto& p : inputs) {
    std::error_code ec;
    if (!fs::is_directory(p, ec)) {
      out.push_back(p);
      continue;
    }
    std::vector<std::string> found;
    for (fs::recursive_directory_iterator it(p, ec), end; !ec && it != end; it.increment(ec)) {
      std::error_code e2;
      if (it->is_regular_file(e2) && exts.count(io::extension_of(it->path().string())))
        found.push_back(it->path().string());
    }
    if (ec) throw IoError(p, "cannot list the folder: " + ec.message());
    if (found.empty()) throw IoError(p, "no PLY, OBJ, OFF, LAS, LAZ or XYZ file in this folder");
    std::sort(found.begin(), found.end());
    out.insert(out.end(), found.begin(), found.end());
  }
  return out;
}

std::string read_small_file(const fs::path& p) {
  std::error_code ec;
  const auto size = fs::file_size(p, ec);
  if (ec) throw IoError(p.string(), "cannot read: " + ec.message());
  if (size > (1u << 20)) throw IoError(p.string(), "too large for a metadata file (> 1 MiB)");
  std::FILE* f = std::fopen(p.c_str(), "rb");
  if (!f) throw IoError(p.string(), std::string("cannot open: ") + std::strerror(errno));
  std::string s(size, '\0');
  const std::size_t got = std::fread(s.data(), 1, s.size(), f);
  std::fclose(f);
  if (got != s.size()) throw IoError(p.string(), "cannot read");
  return s;
}

/// The text of <tag>...</tag> (blanks trimmed); nullopt when absent.
std::optional<std::string> xml_element(const std::string& doc, const std::string& tag) {
  const std::size_t a = doc.find("<" + tag + ">");
  if (a == std::string::npos) return std::nullopt;
  const std::size_t b = doc.find("</" + tag + ">", a);
  if (b == std::string::npos) return std::nullopt;
  std::string v = doc.substr(a + tag.size() + 2, b - a - tag.size() - 2);
  const auto blank = [](unsigned char c) { return std::isspace(c) != 0; };
  while (!v.empty() && blank(static_cast<unsigned char>(v.back()))) v.pop_back();
  std::size_t k = 0;
  while (k < v.size() && blank(static_cast<unsigned char>(v[k]))) ++k;
  return v.substr(k);
}

/// Sidecars of an input: FILE.prj beside it (CRS as WKT), else a ContextCapture
/// metadata.xml in its folder or the two above it (<SRS> and <SRSOrigin>). Records
/// the sidecar files used in `used` (for the up-to-date check).
void read_sidecars(InputInfo& in, std::set<std::string>& used) {
  const fs::path file(in.path);
  fs::path prj = file;
  prj.replace_extension(".prj");
  std::error_code ec;
  if (fs::is_regular_file(prj, ec)) {
    in.sidecar_crs = read_small_file(prj);
    while (!in.sidecar_crs.empty() &&
           std::isspace(static_cast<unsigned char>(in.sidecar_crs.back())))
      in.sidecar_crs.pop_back();
    if (in.sidecar_crs.empty()) throw IoError(prj.string(), "empty .prj file");
    used.insert(fs::absolute(prj).lexically_normal().string());
  }
  fs::path dir = fs::absolute(file).lexically_normal().parent_path();
  for (int up = 0; up < 3 && !dir.empty(); ++up, dir = dir.parent_path()) {
    const fs::path xml = dir / "metadata.xml";
    if (!fs::is_regular_file(xml, ec)) {
      if (dir == dir.root_path()) break;
      continue;
    }
    const std::string doc = read_small_file(xml);
    if (doc.find("<ModelMetadata") == std::string::npos) break;  // someone else's metadata.xml
    used.insert(xml.string());
    const auto srs = xml_element(doc, "SRS");
    if (srs && !srs->empty() && in.sidecar_crs.empty()) {
      if (srs->rfind("ENU:", 0) == 0) {
        const auto ll = parse_triple(srs->substr(4));
        if (!ll) throw IoError(xml.string(), "<SRS>" + *srs + "</SRS>: expected ENU:LAT,LON");
        in.sidecar_origin = srs->substr(4) + ",0";
      } else {
        in.sidecar_crs = *srs;
      }
    }
    if (const auto o = xml_element(doc, "SRSOrigin")) {
      const auto v = parse_triple(*o);
      if (!v) throw IoError(xml.string(), "<SRSOrigin>" + *o + "</SRSOrigin>: expected X,Y,Z");
      in.offset = *v;
    }
    break;
  }
}

/// --crs against the CRS record of a LAS/LAZ file: a unit mismatch (a feet --crs on a
/// file whose record says metres, or the reverse), as geo::declared_unit_conflict words
/// it; "" when they agree or the file says nothing.
std::string unit_conflict(const geo::Crs& declared, const io::FileInfo& info) {
  if (info.format != io::Format::las && info.format != io::Format::laz) return {};
  double unit_m = info.linear_unit_m;
  if (unit_m <= 0 && info.epsg) {
    try {
      const geo::Crs c = geo::Crs::parse("EPSG:" + std::to_string(info.epsg));
      if (c.is_projected()) unit_m = c.horizontal_unit().to_si;
    } catch (const std::exception&) {
    }
  }
  const std::string name = !info.crs_name.empty() ? info.crs_name
                           : info.epsg            ? "EPSG:" + std::to_string(info.epsg)
                                                  : std::string();
  return geo::declared_unit_conflict(declared, name, unit_m, info.vertical_unit_m);
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  const auto mid = v.begin() + static_cast<long>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// ====================================================================== the splitter
class Splitter {
 public:
  Splitter(const SplitOptions& o, const ProgressFn& progress) : opt_(o), stages_(progress) {}

  SplitReport run();

 private:
  void pass1_headers();
  void georeference();
  void choose_cell_size();
  void pass2_spill(Spiller& spill);
  void read_footprints();
  void load_footprints();
  void pass3_cells(const Spiller& spill);
  /// Runs `process(job)` for cells 0..n-1 on the split's threads and merges each
  /// cell's output in order.
  template <class Process>
  void run_cells(std::size_t n, std::size_t progress_from, double progress_total, const char* stage,
                 Process&& process);
  void merge_cell(CellOutput& out);
  void process_cell_clusters(const Spiller& spill, const CellKey& key, double size, bool unmatched,
                             CellJob& job);
  void count_unmatched(const Spiller& spill);
  void drop_footprint_points(RegionPoints& pts, FpCache& fp) const;
  std::size_t footprint_of(const Vec2& q, FpCache& fp) const;
  std::size_t mesh_footprint_of(const FaceRec& f, bool above_ground) const;
  double mesh_planar_share(std::vector<std::uint64_t> tris, const RegionPoints& pts) const;
  void mesh_footprint_members(const RegionPoints& pts, const CellSegmentation& seg,
                              const std::set<std::size_t>& mine,
                              std::map<std::size_t, std::vector<std::uint32_t>>& members) const;
  void process_cell_footprints(const Spiller& spill, const CellKey& key, double size,
                               const std::vector<std::size_t>& owned, CellJob& job);
  [[noreturn]] void region_too_large(const CellKey& key, double size,
                                     const std::string& what) const;
  /// A streamed mesh triangle (its vertex ids and vertices) to the face files of the
  /// cells its xy box meets.
  void spill_face(const std::array<std::uint32_t, 3>& tri,
                  const std::array<VertexStore::Vertex, 3>& v, std::uint64_t t, std::size_t input);
  std::array<double, 4> within_data_reach(std::array<double, 4> box, double margin) const;
  std::size_t load_region(const Spiller& spill, const std::array<double, 4>& box, RegionPoints& out,
                          std::size_t max_points, CellJob& job) const;
  CellOutput::Chunk& emit_chunk(const RegionPoints& pts, const CellSegmentation& seg,
                                const std::vector<std::uint32_t>& members, const std::string& id,
                                const std::string& source, Ring outline, CellOutput& out) const;
  void write_mesh_chunks();
  std::string unique_id(std::string id);

  const SplitOptions& opt_;
  Stages stages_;
  SplitReport rep_;
  std::unique_ptr<Staging> staging_;

  std::vector<InputInfo> inputs_;
  std::string crs_spec_;  // recorded in the manifest
  std::optional<geo::Crs> crs_;
  std::optional<geo::Georef> georef_;
  /// The inputs' common coordinate grid in the scene frame (LAS/LAZ scale per axis,
  /// offsets on it, metres), 0 = none: chunk coordinates are snapped back onto it, so
  /// that the same points give the same bytes wherever they lie (a copy's decoded
  /// coordinates differ in their last bits).
  std::array<double, 3> grid_{0, 0, 0};
  io::BBox3 bbox_crs_;  // union of input boxes (CRS units)
  io::BBox3 bbox_enu_;  // after pass 2
  std::uint64_t total_points_ = 0;
  bool has_normals_ = true, has_colors_ = true, has_classes_ = true;
  std::uint64_t class_hist_[256] = {};
  ClassMode mode_ = ClassMode::none;
  double cell_ = 100;
  std::size_t region_budget_points_ = 0;

  std::set<std::string> sidecars_;  // metadata.xml / .prj files used
  bool mesh_scene_ = false;
  std::unique_ptr<CellFiles<FaceRec>> faces_;    // mesh triangles by the cells they meet
  std::unique_ptr<CellFiles<ClaimRec>> claims_;  // chunk claims by the triangle's cell
  std::size_t subdivided_ = 0;                   // regions processed as quarter cells
  std::size_t fp_few_ = 0, fp_few_points_ = 0;   // footprints with too few building points
  std::size_t fp_few_max_ = 0;                   // ... and the most any of them holds
  double claim_cell_ = 10;  // claims by the smallest cell of their centroid: a file stays small
  std::vector<double> mesh_up_;  // +1 when a mesh's faces point up/out (counter-clockwise), else -1

  FootprintSet fp_set_;         // as read (source CRS), until load_footprints()
  std::string fp_source_;       // for messages
  std::vector<Footprint> fps_;  // ENU, those meeting the data bbox
  std::vector<char> fp_inside_;
  std::map<CellKey, std::vector<std::size_t>> fp_owned_;
  std::unordered_map<CellKey, std::vector<std::size_t>, CellKeyHash> fp_index_;  // 2D bucket index
  double fp_bucket_ = 50;
  /// footprint_of's answers by 1 m cell of a bucket, where one answer holds for the
  /// whole cell (kFpExact: test the point); built on first use, dropped past a bound.
  const std::vector<std::int32_t>& fp_raster(const CellKey& bucket,
                                             const std::vector<std::size_t>& candidates,
                                             FpCache& fp) const;

  std::vector<PendingChunk> chunks_;
  std::set<std::string> ids_;
};

// ---------------------------------------------------------------------- pass 1
void Splitter::pass1_headers() {
  for (auto& in : inputs_) {  // paths, sidecars and offsets from run()
    in.info = io::read_header(in.path);
    in.mesh = in.info.has_faces;
    // OBJ and text files have no header counts: their scan below decides
    if (in.info.point_count == 0 && in.info.format != io::Format::obj &&
        in.info.format != io::Format::xyz)
      throw IoError(in.path, "no points (empty file)");
  }
  // Bounding boxes: the LAS header's, or streamed (also validates the file).
  const double n = static_cast<double>(inputs_.size());
  for (std::size_t i = 0; i < inputs_.size(); ++i) {
    InputInfo& in = inputs_[i];
    if (!(in.info.bbox_from_header && !in.info.bbox.empty())) {
      struct Ctx {
        Stages* s;
        double a, b;
      } ctx{&stages_, 0.05 * double(i) / n, 0.05 * double(i + 1) / n};
      in.info = io::scan_file(
          in.path,
          [](double f, const char*, void* u) {
            auto* c = static_cast<Ctx*>(u);
            c->s->report(c->a, c->b, f, "scan");
            return true;
          },
          &ctx);
      in.mesh = in.info.has_faces;
      if (in.info.point_count == 0) throw IoError(in.path, "no points (empty file)");
    }
    for (int a = 0; a < 3; ++a) {
      in.info.bbox.min[std::size_t(a)] += in.offset[std::size_t(a)];
      in.info.bbox.max[std::size_t(a)] += in.offset[std::size_t(a)];
      if (!std::isfinite(in.info.bbox.min[a]) || !std::isfinite(in.info.bbox.max[a]))
        throw IoError(in.path, "bounding box is not finite");
    }
    bbox_crs_.add(in.info.bbox);
    // a region holds points, or a mesh's samples (>= one a face) and faces: ~3 per face
    total_points_ += in.mesh ? 3 * in.info.face_count : in.info.point_count;
  }
  const bool any_mesh =
      std::any_of(inputs_.begin(), inputs_.end(), [](const auto& i) { return i.mesh; });
  const bool any_points =
      std::any_of(inputs_.begin(), inputs_.end(), [](const auto& i) { return !i.mesh; });
  if (any_mesh && any_points)
    throw std::invalid_argument("mixing meshes and point clouds in one split is not supported");
  mesh_scene_ = any_mesh;
}

// ---------------------------------------------------------------------- georeferencing
/// The scene origin's x and y are multiples of this (CRS units).
constexpr double kOriginGrid = 100;

void Splitter::georeference() {
  const std::string label = inputs_label(inputs_);
  try {
    std::string origin = opt_.origin;
    if (origin.empty() && opt_.crs.empty()) {  // metadata.xml <SRS>ENU:lat,lon for every input
      for (const auto& in : inputs_)
        if (in.sidecar_origin.empty() || in.sidecar_origin != inputs_.front().sidecar_origin ||
            !crs_spec_of(in.info).empty()) {
          origin.clear();
          break;
        } else {
          origin = in.sidecar_origin;
        }
    }
    if (!origin.empty()) {
      georef_.emplace(geo::Georef::local(geo::parse_origin(origin)));
      rep_.notes.push_back(std::string("data in a local ENU frame at ") +
                           (opt_.origin.empty() ? "metadata.xml ENU:" : "--origin ") + origin +
                           " (no CRS)");
      return;
    }
    if (!opt_.crs.empty()) {
      crs_spec_ = opt_.crs;
    } else {
      for (const auto& in : inputs_) {
        std::string s = crs_spec_of(in.info);
        if (s.empty()) s = in.sidecar_crs;
        if (s.empty())
          throw IoError(in.path,
                        "no CRS in the file (nor in a .prj or metadata.xml beside it); pass --crs "
                        "EPSG:nnnn (or --origin LAT,LON,H for local data)");
        if (!crs_spec_.empty() && s != crs_spec_)
          throw IoError(in.path,
                        "its CRS differs from that of " + inputs_.front().path + "; pass --crs");
        crs_spec_ = s;
      }
    }
    crs_.emplace(geo::Crs::parse(crs_spec_));
    crs_->require_projected("to split a scene");
    if (!opt_.crs.empty())
      for (const auto& in : inputs_) {
        const std::string conflict = unit_conflict(*crs_, in.info);
        if (!conflict.empty()) throw IoError(in.path, conflict);
      }
    if (opt_.geoid == "egm96") {  // the explicit model wins over the CRS's (implied) datum
      geo::TransformOptions to;
      to.height = geo::HeightMode::Egm96;
      georef_.emplace(geo::Georef::from_crs_bbox(*crs_, to_eigen(bbox_crs_), to));
      rep_.vertical = "heights orthometric (--geoid egm96) -> ellipsoidal via EGM96";
    } else {
      const geo::VerticalMode mode =
          opt_.vertical.empty() ? geo::VerticalMode::Auto : geo::parse_vertical_mode(opt_.vertical);
      geo::VerticalChoice vc = geo::choose_vertical(*crs_, mode);
      georef_.emplace(
          vc.transformer
              ? geo::Georef::from_transformer_bbox(std::move(vc.transformer), to_eigen(bbox_crs_))
              : geo::Georef::from_crs_bbox(vc.crs, to_eigen(bbox_crs_), vc.options));
      rep_.vertical = vc.assumption;
      for (const auto& w : vc.warnings) rep_.notes.push_back(w);
    }
    // The scene frame: the CRS's axes in metres from an origin on a 100-unit grid
    // (geo::SceneFrame::projected): a building's points get the same coordinates
    // wherever it lies (the same model), and grids anchored at the scene origin (the
    // cells) fall alike on copies shifted by whole 100 units.
    {
      const Eigen::Vector3d c = to_eigen(bbox_crs_).center();
      georef_->use_projected_frame(Eigen::Vector3d(std::round(c[0] / kOriginGrid) * kOriginGrid,
                                                   std::round(c[1] / kOriginGrid) * kOriginGrid,
                                                   std::round(c[2])));
    }
    if (crs_->horizontal_unit().to_si == 1.0 && crs_->vertical_unit().to_si == 1.0)
      for (int k = 0; k < 3; ++k) {
        const double step = inputs_.front().info.scale[std::size_t(k)];
        bool ok = step > 0 && std::isfinite(step);
        const double per_unit = ok ? std::round(1.0 / step) : 0;  // steps per metre
        ok = ok && per_unit >= 1 && std::fabs(per_unit * step - 1.0) < 1e-9;
        for (const auto& in : inputs_) {
          const double o = in.info.offset[std::size_t(k)] + in.offset[std::size_t(k)];
          ok = ok && in.info.scale[std::size_t(k)] == step &&
               std::fabs(o * per_unit - std::round(o * per_unit)) < 1e-6;
        }
        grid_[std::size_t(k)] = ok ? step : 0;
      }
    rep_.notes.push_back(rep_.vertical);
    rep_.crs = crs_->label();
    const auto& hu = crs_->horizontal_unit();
    if (std::abs(hu.to_si - 1.0) > 1e-12)
      rep_.notes.push_back("coordinates in " + hu.name + " (" + fmt("%.10g", hu.to_si) +
                           " m) converted to metres");
    const auto& vu = crs_->vertical_unit();
    if (std::abs(vu.to_si - 1.0) > 1e-12)
      rep_.notes.push_back("heights in " + vu.name + " (" + fmt("%.10g", vu.to_si) +
                           " m) converted to metres");
    for (const auto& w : georef_->warnings())
      if (std::find(rep_.notes.begin(), rep_.notes.end(), w) == rep_.notes.end())
        rep_.notes.push_back(w);
    for (const auto& w : geo::check_units(*crs_, to_eigen(bbox_crs_)).warnings)
      rep_.notes.push_back(w);
  } catch (const geo::GeoError& e) {
    throw IoError(label, e.what());
  }
}

// ---------------------------------------------------------------------- memory plan
// Processing a region costs about kRegionBytesPerPoint (points + attributes +
// PCL clouds + kd-trees + labels); spilling buffers take a quarter of the budget.
constexpr double kRegionBytesPerPoint = 400;
// Cells are halved (the initial grid from the average density, then a region that
// exceeds the budget processed as quarters) while larger than this: the grids of all
// memory limits nest, so a limit that passes is passed by every higher one.
constexpr double kMinSplitCell = 10;

void Splitter::choose_cell_size() {
  region_budget_points_ =
      static_cast<std::size_t>(0.45 * double(opt_.memory_limit) / kRegionBytesPerPoint);
  cell_ = opt_.cell_size;
  // Density from the header counts over the (CRS) box, in points per m^2 (units converted).
  double to_m = 1;
  if (crs_) to_m = crs_->horizontal_unit().to_si;
  const double area = std::max(1.0, (bbox_crs_.max[0] - bbox_crs_.min[0]) *
                                        (bbox_crs_.max[1] - bbox_crs_.min[1]) * to_m * to_m);
  const double density = double(total_points_) / area;
  while (cell_ > kMinSplitCell && (cell_ + 2 * opt_.halo) * (cell_ + 2 * opt_.halo) * density >
                                      0.5 * double(region_budget_points_))
    cell_ *= 0.5;
  if (cell_ != opt_.cell_size)
    rep_.notes.push_back("cell size reduced to " + fmt("%.1f", cell_) + " m to fit --memory-limit");
  rep_.cell_size = cell_;
  claim_cell_ = cell_;
  while (claim_cell_ > kMinSplitCell) claim_cell_ *= 0.5;
}

// ---------------------------------------------------------------------- pass 2
void Splitter::pass2_spill(Spiller& spill) {
  for (const auto& in : inputs_) {
    if (!in.info.has_normals) has_normals_ = false;
    if (!in.info.has_colors) has_colors_ = false;
    if (!in.info.has_classes) has_classes_ = false;
  }
  io::BBox3 seen_crs;
  const double n_in = static_cast<double>(inputs_.size());
  const std::string label = inputs_label(inputs_);
  for (std::size_t ii = 0; ii < inputs_.size(); ++ii) {
    const InputInfo& in = inputs_[ii];
    const double a = 0.05 + 0.45 * double(ii) / n_in, b = 0.05 + 0.45 * double(ii + 1) / n_in;
    // Point k of a batch as a spill record (position, normal, colour); grows the ENU bbox.
    auto to_rec = [&](const io::PointSet& batch, std::size_t k) {
      const Vec3d& p = batch.positions[k];
      bbox_enu_.add(p);
      SpillRec r{};
      r.x = p[0];
      r.y = p[1];
      r.z = p[2];
      if (has_normals_) {
        r.nx = batch.normals[k][0];
        r.ny = batch.normals[k][1];
        r.nz = batch.normals[k][2];
      }
      if (has_colors_) {
        r.r = batch.colors[k][0];
        r.g = batch.colors[k][1];
        r.b = batch.colors[k][2];
      }
      return r;
    };
    auto push = [&](const io::PointSet& batch, std::uint64_t first_src, bool mesh) {
      for (std::size_t k = 0; k < batch.size(); ++k) {
        const Vec3d& p = batch.positions[k];
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
          throw IoError(in.path, "point #" + std::to_string(first_src + k) +
                                     " has no valid local coordinates (CRS transform failed)");
        SpillRec r = to_rec(batch, k);
        if (has_classes_) {
          r.cls = batch.classes[k];
          ++class_hist_[r.cls];
        }
        r.src = mesh ? ((std::uint64_t(ii) << 40) | (first_src + k)) : kNoSrc;
        spill.add(r);
      }
    };
    // Mesh samples: `refs[k]` is the triangle of sample k.
    auto push_refs = [&](io::PointSet& batch, const std::vector<std::uint64_t>& refs,
                         std::size_t input) {
      for (std::size_t k = 0; k < batch.size(); ++k) {
        const Vec3d& p = batch.positions[k];
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
          throw IoError(in.path,
                        "triangle #" + std::to_string(refs[k]) + " has no valid local coordinates");
        SpillRec r = to_rec(batch, k);
        r.src = (std::uint64_t(input) << 40) | refs[k];
        spill.add(r);
      }
      batch.clear();
    };
    auto to_local = [&](auto& v) {
      if (v.empty()) return;
      if (in.offset != Vec3d{0, 0, 0})
        for (auto& p : v) p = {p[0] + in.offset[0], p[1] + in.offset[1], p[2] + in.offset[2]};
      for (const auto& p : v) seen_crs.add(p);
      Eigen::Map<Eigen::Matrix3Xd> m(v[0].data(), 3, static_cast<Eigen::Index>(v.size()));
      try {
        georef_->to_local_inplace(m);
      } catch (const geo::GeoError& e) {
        throw IoError(in.path, e.what());
      }
    };
    if (in.mesh) {
      // A mesh file is streamed: its vertices are kept (ENU doubles, plus the file's own
      // coordinates when it has polygons to triangulate, plus the attributes the split
      // uses; in memory up to half of --memory-limit, else paged from a file through a
      // cache of that size), its faces are read in batches, sampled and spilled to their
      // cells.
      const bool polygons = in.info.max_face_corners > 3;
      const std::uint64_t vertex_budget =
          opt_.mesh_vertex_budget > 0 ? opt_.mesh_vertex_budget : opt_.memory_limit / 2;
      auto reader = io::MeshReader::open(in.path);
      VertexStore mv({polygons, has_normals_, has_colors_}, in.info.point_count, vertex_budget,
                     staging_->scratch("vertices_" + std::to_string(ii)).string());
      {
        io::PointSet vb;
        std::vector<Vec3d> file;
        bool all_normals = true, all_colors = true;
        while (reader->read_vertices(vb, 1 << 16) > 0) {
          all_normals = all_normals && vb.has_normals();
          all_colors = all_colors && vb.has_colors();
          if (polygons) file = vb.positions;  // triangulated in these, as read_mesh()
          to_local(vb.positions);
          mv.append(vb.positions.data(), polygons ? file.data() : nullptr,
                    all_normals && vb.has_normals() ? vb.normals.data() : nullptr,
                    all_colors && vb.has_colors() ? vb.colors.data() : nullptr, vb.size());
        }
        mv.finish();
        if (!all_normals) has_normals_ = false;
        if (!all_colors) has_colors_ = false;
      }
      if (mv.paged())
        rep_.notes.push_back(in.path + ": " + std::to_string(mv.size()) + " vertices (" +
                             fmt("%.0f", double(mv.size() * mv.record_bytes()) / 1048576) +
                             " MiB) paged from the work directory while the faces stream");
      // Triangles are sampled (centroid + ~kMeshSamplesPerM2 per m^2): the samples are
      // segmented like points and vote for their triangle's building.
      io::PointSet ps;
      std::vector<std::uint64_t> tri_of;  // sample -> triangle, per batch
      std::uint64_t rng = 0x9E3779B97F4A7C15ULL;
      auto uni = [&rng]() {
        rng = rng * 6364136223846793005ULL + 1442695040888963407ULL;
        return double(rng >> 11) / double(1ull << 53);
      };
      // Orientation of the whole mesh: the signed xy area of a city surface (terrain and
      // roofs seen from above) is positive when its faces point up/out. The wall rule of
      // mesh_footprint_of() needs the outward side of each face.
      double up = 0;
      std::uint64_t t = 0;  // triangle index in the file (after triangulation)
      io::FaceBatch fb;
      std::vector<std::array<std::uint32_t, 3>> tris;
      std::vector<Vec3d> corners;  // a polygon's corners (file coordinates)
      std::uint64_t faces_read = 0;
      while (reader->read_faces(fb, 1 << 16) > 0) {
        faces_read += fb.size();
        tris.clear();
        for (std::size_t f = 0; f < fb.size(); ++f) {
          const std::uint32_t* face = fb.face(f);
          const std::size_t n = fb.face_size(f);
          corners.clear();
          for (std::size_t k = 0; n > 3 && k < n; ++k) {  // triangles read as they are
            const VertexStore::Vertex c = mv.get(face[k]);
            corners.push_back(polygons ? c.file : c.pos);
          }
          io::triangulate_face(corners.data(), face, n, tris);
        }
        for (const auto& tri : tris) {
          const std::array<VertexStore::Vertex, 3> cv{mv.get(tri[0]), mv.get(tri[1]),
                                                      mv.get(tri[2])};
          const Vec3d& p0 = cv[0].pos;
          const Vec3d& p1 = cv[1].pos;
          const Vec3d& p2 = cv[2].pos;
          const Eigen::Vector3d e1(p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]);
          const Eigen::Vector3d e2(p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]);
          const double area = 0.5 * e1.cross(e2).norm();
          const std::size_t n =
              1 + static_cast<std::size_t>(std::min(1e6, area * kMeshSamplesPerM2));
          for (std::size_t k = 0; k < n; ++k) {
            double u = 1.0 / 3, v = 1.0 / 3;
            if (k > 0) {
              u = uni();
              v = uni();
              if (u + v > 1) u = 1 - u, v = 1 - v;
            }
            ps.positions.push_back({p0[0] + u * e1[0] + v * e2[0], p0[1] + u * e1[1] + v * e2[1],
                                    p0[2] + u * e1[2] + v * e2[2]});
            if (has_normals_) ps.normals.push_back(cv[0].normal);
            if (has_colors_) ps.colors.push_back(cv[0].color);
            tri_of.push_back(t);
          }
          if (ps.size() >= (1u << 16)) {
            push_refs(ps, tri_of, ii);
            tri_of.clear();
          }
          up += (p1[0] - p0[0]) * (p2[1] - p0[1]) - (p1[1] - p0[1]) * (p2[0] - p0[0]);
          spill_face(tri, cv, t, ii);
          ++t;
        }
        stages_.report(a, b,
                       double(faces_read) / double(std::max<std::uint64_t>(1, in.info.face_count)),
                       "ingest");
      }
      if (!ps.empty()) push_refs(ps, tri_of, ii);
      mesh_up_.resize(ii + 1);
      mesh_up_[ii] = up < 0 ? -1.0 : 1.0;
      if (up < 0 && !opt_.footprints.empty())
        rep_.notes.push_back(in.path +
                             ": faces point down (clockwise seen from above); taken as "
                             "reversed for the wall-to-footprint test");
      rep_.points += mv.size();
      rep_.triangles += t;
      stages_.report(a, b, 1.0, "ingest");
      continue;
    }
    auto reader = io::PointReader::open(in.path);
    io::PointSet batch;
    std::uint64_t first = 0;
    while (true) {
      const std::size_t got = reader->read(batch, 1 << 16);
      if (got == 0) break;
      to_local(batch.positions);
      push(batch, first, false);
      first += got;
      stages_.report(a, b, reader->progress(), "ingest");
    }
    if (first == 0) throw IoError(in.path, "no points (empty file)");
    rep_.points += first;
  }
  spill.flush();
  spill.release();
  if (faces_) faces_->flush();
  if (bbox_enu_.empty()) throw IoError(label, "no points");

  // A LAS header box that lies: check the area of use again with the real box.
  if (crs_) {
    const double ex =
        std::max(bbox_crs_.max[0] - bbox_crs_.min[0], bbox_crs_.max[1] - bbox_crs_.min[1]);
    const double tol = 1e-6 * std::max(1.0, ex) + 0.01;
    bool outside = false;
    for (int a = 0; a < 3; ++a)
      if (seen_crs.min[a] < bbox_crs_.min[a] - tol || seen_crs.max[a] > bbox_crs_.max[a] + tol)
        outside = true;
    if (outside) {
      rep_.notes.push_back("points lie outside the header bounding box of " + label);
      try {
        geo::TransformOptions to;
        geo::Transformer t(*crs_, to);
        t.check_in_area(to_eigen(seen_crs));
      } catch (const geo::GeoError& e) {
        throw IoError(label, e.what());
      }
    }
  }

  // How classes can be used.
  if (opt_.ignore_classes || !has_classes_)
    mode_ = ClassMode::none;
  else if (class_hist_[2] > 0 && class_hist_[6] > 0)
    mode_ = ClassMode::buildings;
  else if (class_hist_[2] > 0)
    mode_ = ClassMode::ground;
  else
    mode_ = ClassMode::none;
  rep_.class_mode = class_mode_name(mode_);
  rep_.bbox = bbox_enu_;
  rep_.spill_bytes = spill.bytes();
}

// A mesh triangle to the face files of every cell its xy box meets (a region then holds
// every triangle of its samples).
void Splitter::spill_face(const std::array<std::uint32_t, 3>& tri,
                          const std::array<VertexStore::Vertex, 3>& v, std::uint64_t t,
                          std::size_t input) {
  FaceRec f{};
  f.id = (std::uint64_t(input) << 40) | t;
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (std::size_t k = 0; k < 3; ++k) {
    const std::uint32_t vi = tri[k];
    f.vid[k] = (std::uint64_t(input) << 40) | vi;
    const Vec3d& p = v[k].pos;
    for (std::size_t a = 0; a < 3; ++a) f.v[k][a] = p[a];
    if (has_normals_)
      for (std::size_t a = 0; a < 3; ++a) f.n[k][a] = v[k].normal[a];
    if (has_colors_)
      for (std::size_t a = 0; a < 3; ++a) f.rgb[k][a] = v[k].color[a];
    x0 = std::min(x0, p[0]), x1 = std::max(x1, p[0]);
    y0 = std::min(y0, p[1]), y1 = std::max(y1, p[1]);
  }
  const CellKey lo = key_at(x0, y0, cell_), hi = key_at(x1, y1, cell_);
  for (int i = lo.first; i <= hi.first; ++i)
    for (int j = lo.second; j <= hi.second; ++j) faces_->add({i, j}, f);
}

// ---------------------------------------------------------------------- footprints
// Read before the points (a bad source, layer or id fails fast); placed in load_footprints().
void Splitter::read_footprints() {
  FootprintSourceOptions fo;
  fo.layer = opt_.footprints_layer;
  fo.id_attribute = opt_.footprints_id;
  fp_set_ = read_footprint_source(opt_.footprints, fo);
}

void Splitter::load_footprints() {
  FootprintSet set = std::move(fp_set_);
  const std::string src = set.source;  // as given, a "PG:" password masked
  fp_source_ = src;
  rep_.footprints_total = set.footprints.size();
  rep_.footprints_repaired = set.repaired;
  rep_.footprints_skipped = set.skipped;
  constexpr std::size_t kMaxProblemNotes = 20;  // the rest counted: notes stay readable
  for (std::size_t i = 0; i < set.problems.size() && i < kMaxProblemNotes; ++i)
    rep_.notes.push_back("footprints: " + set.problems[i]);
  if (set.problems.size() > kMaxProblemNotes)
    rep_.notes.push_back("footprints: " + std::to_string(set.problems.size() - kMaxProblemNotes) +
                         " more features skipped or repaired (" + std::to_string(set.repaired) +
                         " repaired, " + std::to_string(set.skipped) + " skipped in all)");
  if (set.footprints.empty())
    throw IoError(
        src,
        set.source_features == 0
            ? "no footprints (layer '" + set.layer + "' is empty)"
            : "none of its " + std::to_string(set.source_features) +
                  " features is a usable polygon (" +
                  (set.problems.empty()
                       ? std::string("none has a polygon geometry")
                       : set.problems.front() +
                             (set.problems.size() > 1
                                  ? "; and " + std::to_string(set.problems.size() - 1) + " more"
                                  : std::string())) +
                  ")");
  // The source's extent, in its own units (for messages and the lon/lat test).
  double ext[4] = {1e300, 1e300, -1e300, -1e300};
  for (const auto& f : set.footprints) {
    ext[0] = std::min(ext[0], f.bbox[0]);
    ext[1] = std::min(ext[1], f.bbox[1]);
    ext[2] = std::max(ext[2], f.bbox[2]);
    ext[3] = std::max(ext[3], f.bbox[3]);
  }
  // To ENU: through the scene georef when the source has no CRS or the scene's; else
  // via WGS84. GeoJSON without a "crs" member is WGS84 for OGR (RFC 7946); legacy
  // files hold projected coordinates anyway: out of lon/lat range -> the scene's CRS.
  std::unique_ptr<geo::Transformer> other;
  try {
    if (!set.crs.empty() && crs_) {
      geo::Crs fcrs = geo::Crs::parse(set.crs);
      const bool same = fcrs.epsg() && crs_->epsg() && *fcrs.epsg() == *crs_->epsg();
      const bool not_lonlat =
          !fcrs.is_projected() && (std::abs(ext[0]) > 360 || std::abs(ext[2]) > 360 ||
                                   std::abs(ext[1]) > 90 || std::abs(ext[3]) > 90);
      if (not_lonlat)
        rep_.notes.push_back("footprints: " + src + " says " + set.crs +
                             " but its coordinates are not longitudes/latitudes; taken in " +
                             crs_->label());
      else if (!same)
        other = std::make_unique<geo::Transformer>(fcrs);
    } else if (set.crs.empty() && crs_) {
      rep_.notes.push_back("footprints: " + src + " has no CRS; taken in " + crs_->label());
    }
    const double z0 = georef_->origin_crs()[2];
    for (auto& f : set.footprints) {
      for (auto& poly : f.polygons)
        for (auto& ring : poly.rings)
          for (auto& v : ring) {
            Eigen::Vector3d e;
            if (other) {
              geo::LonLatH g = other->to_wgs84(Eigen::Vector3d(v[0], v[1], 0));
              g[2] = georef_->frame().origin()[2];
              e = georef_->from_geodetic(g);
            } else {
              e = georef_->to_local(Eigen::Vector3d(v[0], v[1], z0));
            }
            if (!std::isfinite(e[0]) || !std::isfinite(e[1]))
              throw IoError(src, "footprint '" + f.id + "' cannot be transformed to the scene CRS");
            // on a micrometre grid: the same footprint gives the same outline wherever
            // it lies (its source's coordinates, shifted, differ in their last bits)
            v = {std::round(e[0] * 1e6) / 1e6, std::round(e[1] * 1e6) / 1e6};
          }
      for (auto& poly : f.polygons) normalise(poly);
      f.update_bbox();
    }
  } catch (const geo::GeoError& e) {
    throw IoError(src, e.what());
  }
  const double buf = opt_.footprint_buffer;
  std::set<std::string> seen;
  for (auto& f : set.footprints) {
    if (f.bbox[2] + buf < bbox_enu_.min[0] || f.bbox[0] - buf > bbox_enu_.max[0] ||
        f.bbox[3] + buf < bbox_enu_.min[1] || f.bbox[1] - buf > bbox_enu_.max[1])
      continue;
    if (!seen.insert(f.id).second)
      throw IoError(
          src, "duplicate footprint id '" + f.id + "'" +
                   (opt_.footprints_id.empty() ? " (choose another with --footprints-id)" : ""));
    const bool inside = f.bbox[0] >= bbox_enu_.min[0] && f.bbox[2] <= bbox_enu_.max[0] &&
                        f.bbox[1] >= bbox_enu_.min[1] && f.bbox[3] <= bbox_enu_.max[1];
    fp_inside_.push_back(inside);
    fps_.push_back(std::move(f));
  }
  if (fps_.empty()) {
    char b[512];
    std::snprintf(b, sizeof b,
                  "none of its %zu footprints meets the data (footprints span %.3f %.3f .. %.3f "
                  "%.3f in %s; the points %.3f %.3f .. %.3f %.3f in %s): wrong CRS or wrong area?",
                  set.footprints.size(), ext[0], ext[1], ext[2], ext[3],
                  set.crs.empty() ? "no CRS" : set.crs.substr(0, 40).c_str(), bbox_crs_.min[0],
                  bbox_crs_.min[1], bbox_crs_.max[0], bbox_crs_.max[1],
                  crs_ ? crs_->label().c_str() : "the local frame");
    throw IoError(src, b);
  }
  rep_.footprints_in_scene = fps_.size();
  for (char c : fp_inside_) rep_.footprints_inside += c ? 1 : 0;
  // Bucket ranges stay within the data box: a huge footprint costs no more than the scene.
  const auto bucket = [&](double v) { return int(std::floor(v / fp_bucket_)); };
  const int bx_lo = bucket(bbox_enu_.min[0] - buf), bx_hi = bucket(bbox_enu_.max[0] + buf);
  const int by_lo = bucket(bbox_enu_.min[1] - buf), by_hi = bucket(bbox_enu_.max[1] + buf);
  for (std::size_t i = 0; i < fps_.size(); ++i) {
    const Vec2 c = fps_[i].centroid();
    fp_owned_[{int(std::floor(c[0] / cell_)), int(std::floor(c[1] / cell_))}].push_back(i);
    const auto& b = fps_[i].bbox;
    for (int bx = std::max(bx_lo, bucket(b[0] - buf)); bx <= std::min(bx_hi, bucket(b[2] + buf));
         ++bx)
      for (int by = std::max(by_lo, bucket(b[1] - buf)); by <= std::min(by_hi, bucket(b[3] + buf));
           ++by)
        fp_index_[{bx, by}].push_back(i);
  }
}

constexpr double kFpRasterCell = 1.0;           ///< m, cell of footprint_of's answer raster
constexpr std::int32_t kFpExact = -1;           ///< raster: the cell needs the exact test
constexpr std::int32_t kFpNone = -2;            ///< raster: no footprint for any point of it
constexpr std::size_t kFpRasterBuckets = 1024;  ///< rasters kept (10 KB each at 50 m / 1 m)

// A cell's answer is the exact test's for every point of it, or kFpExact. In the exact
// test's order (increasing index): a footprint whose box + buffer misses the cell is
// skipped for all its points; one whose boundary lies farther than the cell's
// half-diagonal from the cell's centre holds all of the cell (the answer, as the test
// stops at the first footprint holding the point) or none of it, and then is within the
// buffer of none of it when that distance exceeds the buffer too.
const std::vector<std::int32_t>& Splitter::fp_raster(const CellKey& bucket,
                                                     const std::vector<std::size_t>& candidates,
                                                     FpCache& fp) const {
  auto it = fp.raster.find(bucket);
  if (it != fp.raster.end()) return it->second;
  if (fp.raster.size() >= kFpRasterBuckets) fp.raster.clear();
  fp.queries.erase(bucket);
  const int n = int(std::ceil(fp_bucket_ / kFpRasterCell));
  const double buf = opt_.footprint_buffer;
  const double half = 0.5 * kFpRasterCell, reach = half * std::sqrt(2.0) + 1e-6;
  std::vector<std::int32_t> r(std::size_t(n) * std::size_t(n), kFpNone);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const Vec2 m{bucket.first * fp_bucket_ + (i + 0.5) * kFpRasterCell,
                   bucket.second * fp_bucket_ + (j + 0.5) * kFpRasterCell};
      std::int32_t answer = kFpNone;
      for (const std::size_t f : candidates) {
        const auto& b = fps_[f].bbox;
        if (m[0] + half < b[0] - buf || m[0] - half > b[2] + buf || m[1] + half < b[1] - buf ||
            m[1] - half > b[3] + buf)
          continue;
        double edge = std::numeric_limits<double>::infinity();
        for (const auto& poly : fps_[f].polygons)
          for (const auto& ring : poly.rings) edge = std::min(edge, distance_to_ring(ring, m));
        if (edge <= reach) {
          answer = kFpExact;
          break;
        }
        if (point_in_footprint(fps_[f], m)) {
          answer = std::int32_t(f);
          break;
        }
        if (edge - reach <= buf) {
          answer = kFpExact;
          break;
        }
      }
      r[std::size_t(j) * std::size_t(n) + std::size_t(i)] = answer;
    }
  return fp.raster.emplace(bucket, std::move(r)).first->second;
}

/// The footprint a point belongs to: the one containing it, else the nearest within
/// the buffer (ties to the first); SIZE_MAX when none. The bucket's raster answers
/// for most points; the points of cells it cannot answer for are tested.
std::size_t Splitter::footprint_of(const Vec2& q, FpCache& fp) const {
  const CellKey bk{int(std::floor(q[0] / fp_bucket_)), int(std::floor(q[1] / fp_bucket_))};
  auto it = fp_index_.find(bk);
  if (it == fp_index_.end()) return SIZE_MAX;
  // A raster costs about as much as testing one point per cell: built for a bucket once
  // it has been asked that often (sparse data, huge rings: the points are tested).
  const int n = int(std::ceil(fp_bucket_ / kFpRasterCell));
  const bool rasterise = fp.raster.count(bk) > 0 || (fps_.size() < std::size_t(INT32_MAX) &&
                                                     ++fp.queries[bk] >= std::uint32_t(n * n));
  if (rasterise) {
    const std::vector<std::int32_t>& r = fp_raster(bk, it->second, fp);
    const int i =
        std::clamp(int(std::floor((q[0] - bk.first * fp_bucket_) / kFpRasterCell)), 0, n - 1);
    const int j =
        std::clamp(int(std::floor((q[1] - bk.second * fp_bucket_) / kFpRasterCell)), 0, n - 1);
    const std::int32_t a = r[std::size_t(j) * std::size_t(n) + std::size_t(i)];
    if (a == kFpNone) return SIZE_MAX;
    if (a >= 0) return std::size_t(a);
  }
  const double buf = opt_.footprint_buffer;
  std::size_t best = SIZE_MAX;
  double best_d = std::numeric_limits<double>::infinity();
  for (std::size_t i : it->second) {  // increasing index: ties go to the first footprint
    const auto& b = fps_[i].bbox;
    if (q[0] < b[0] - buf || q[0] > b[2] + buf || q[1] < b[1] - buf || q[1] > b[3] + buf) continue;
    const double d = distance_to_footprint(fps_[i], q);
    if (d < best_d) {
      best = i;
      best_d = d;
      if (d == 0) break;
    }
  }
  return best_d > buf ? SIZE_MAX : best;
}

// Mesh triangles are judged whole, by their geometry (no foliage test: the faces a
// footprint claims are all kept). A face no steeper than 60 degrees (roof, terrain)
// goes to the footprint holding the largest share of its xy projection when that share
// is at least kMeshMinShare; otherwise (eaves, overhangs) to the footprint nearest to its
// centroid within --footprint-buffer. A steeper face (wall) goes to the footprint that
// holds the point --footprint-buffer behind it (against its outward normal), preferring
// one that does not also hold the point as far in front of it: on a footprint edge
// shared by touching buildings the wall belongs to the building it bounds, not to the
// one it faces; else to the nearest footprint within the buffer. Faces whose samples
// all lie on the ground (DTM) are never claimed, except walls found by the rule above.
constexpr double kMeshMinShare = 0.5;      ///< share of a face's xy area inside a footprint
constexpr double kMeshWallCos = 0.5;       ///< |n_z| below this (steeper than 60 deg): a wall
constexpr double kMeshMinWallProbe = 0.2;  ///< m, the probe distance when the buffer is 0

std::size_t Splitter::mesh_footprint_of(const FaceRec& f, bool above_ground) const {
  const Vec3d p0{f.v[0][0], f.v[0][1], f.v[0][2]};
  const Vec3d p1{f.v[1][0], f.v[1][1], f.v[1][2]};
  const Vec3d p2{f.v[2][0], f.v[2][1], f.v[2][2]};
  const Eigen::Vector3d e1(p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]);
  const Eigen::Vector3d e2(p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]);
  const Eigen::Vector3d n = e1.cross(e2) * mesh_up_[std::size_t(f.id >> 40)];
  const double len = n.norm();
  const Vec2 c{(p0[0] + p1[0] + p2[0]) / 3, (p0[1] + p1[1] + p2[1]) / 3};
  const double buf = opt_.footprint_buffer;
  // Candidates: footprints whose buffered bbox meets the triangle's xy bbox, in index order.
  std::vector<std::size_t> cand;
  const double bx0 = std::min({p0[0], p1[0], p2[0]}), bx1 = std::max({p0[0], p1[0], p2[0]});
  const double by0 = std::min({p0[1], p1[1], p2[1]}), by1 = std::max({p0[1], p1[1], p2[1]});
  for (int bx = int(std::floor(bx0 / fp_bucket_)); bx <= int(std::floor(bx1 / fp_bucket_)); ++bx)
    for (int by = int(std::floor(by0 / fp_bucket_)); by <= int(std::floor(by1 / fp_bucket_));
         ++by) {
      const auto it = fp_index_.find({bx, by});
      if (it == fp_index_.end()) continue;
      for (std::size_t i : it->second) {
        const auto& b = fps_[i].bbox;
        if (bx1 < b[0] - buf || bx0 > b[2] + buf || by1 < b[1] - buf || by0 > b[3] + buf) continue;
        cand.push_back(i);
      }
    }
  if (cand.empty()) return SIZE_MAX;
  std::sort(cand.begin(), cand.end());
  cand.erase(std::unique(cand.begin(), cand.end()), cand.end());
  const auto nearest = [&](const Vec2& q) {
    std::size_t best = SIZE_MAX;
    double best_d = std::numeric_limits<double>::infinity();
    for (std::size_t i : cand) {
      const double d = distance_to_footprint(fps_[i], q);
      if (d < best_d) best = i, best_d = d;
    }
    return best_d > buf ? SIZE_MAX : best;
  };
  if (!(len > 0)) return above_ground ? nearest(c) : SIZE_MAX;
  if (std::abs(n[2]) >= kMeshWallCos * len) {  // roof, terrain: by area
    Ring xy{{p0[0], p0[1]}, {p1[0], p1[1]}, {p2[0], p2[1]}};
    if (signed_area(xy) < 0) std::swap(xy[1], xy[2]);
    const double a = std::abs(signed_area(xy));
    std::size_t best = SIZE_MAX;
    double best_a = 0;
    for (std::size_t i : cand) {
      const double ai = area_inside(fps_[i], xy);
      if (ai > best_a) best = i, best_a = ai;
    }
    if (!above_ground) return SIZE_MAX;
    if (best != SIZE_MAX && best_a >= kMeshMinShare * a) return best;
    return nearest(c);
  }
  // wall: the footprint it bounds
  const double h = std::hypot(n[0], n[1]);
  const double probe = std::max(buf, kMeshMinWallProbe);
  const Vec2 back{c[0] - probe * n[0] / h, c[1] - probe * n[1] / h};
  const Vec2 front{c[0] + probe * n[0] / h, c[1] + probe * n[1] / h};
  std::size_t inside = SIZE_MAX;
  for (std::size_t i : cand) {
    if (!point_in_footprint(fps_[i], back)) continue;
    if (!point_in_footprint(fps_[i], front)) return i;
    if (inside == SIZE_MAX) inside = i;
  }
  if (inside != SIZE_MAX) return inside;
  return above_ground ? nearest(c) : SIZE_MAX;
}

// The samples of every triangle whose footprint (mesh_footprint_of) is one of `mine`.
void Splitter::mesh_footprint_members(
    const RegionPoints& pts, const CellSegmentation& seg, const std::set<std::size_t>& mine,
    std::map<std::size_t, std::vector<std::uint32_t>>& members) const {
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> samples;
  std::unordered_map<std::uint64_t, bool> high;
  for (std::size_t k = 0; k < pts.pos.size(); ++k) {
    const std::uint64_t s = pts.src[k];
    samples[s].push_back(static_cast<std::uint32_t>(k));
    bool& h = high[s];
    h = h || (!seg.ground[k] && seg.hag[k] >= opt_.seg.ground_tolerance);
  }
  std::vector<std::uint64_t> tris;
  tris.reserve(samples.size());
  for (const auto& [s, v] : samples) tris.push_back(s);
  std::sort(tris.begin(), tris.end());  // sample order in each chunk: by triangle
  for (std::uint64_t s : tris) {
    const std::size_t f = mesh_footprint_of(pts.face(s), high[s]);
    if (f == SIZE_MAX || !mine.count(f)) continue;
    auto& dst = members[f];
    const auto& v = samples[s];
    dst.insert(dst.end(), v.begin(), v.end());
  }
}

// Trees on meshes: MVS meshes make crowns smooth closed blobs, which the point
// features (PCA scatter of small neighbourhoods) take for roofs. A building is made of
// planar faces of several m^2; a crown is curved at that scale. The triangles of a
// cluster are grown into planar regions over shared edges (a neighbour joins when its
// normal is within kMeshPlanarAngle of the region's plane and its vertices within
// kMeshPlanarTolerance of it; the plane is refitted as the region doubles); the share of
// the area in regions of >= kMeshPlanarRegionArea decides (< kMeshMinPlanarShare: a tree).
// Measured: mesh_city crowns 0.00-0.10, its building groups 0.87-0.93; noisier real meshes
// less: easy3d_building.off 0.34, the b9 urban block 0.47.
// Returns -1 (no decision) for triangle soups without shared edges.
constexpr double kMeshPlanarTolerance = 0.15;  ///< m (3 sigma of the 5 cm MVS noise)
constexpr double kMeshPlanarAngle = 30;        ///< degrees
constexpr double kMeshPlanarRegionArea = 6;    ///< m^2
constexpr double kMeshMinPlanarShare = 0.2;

double Splitter::mesh_planar_share(std::vector<std::uint64_t> tris, const RegionPoints& pts) const {
  std::sort(tris.begin(), tris.end());
  tris.erase(std::unique(tris.begin(), tris.end()), tris.end());
  const std::size_t n = tris.size();
  if (n == 0) return -1;
  std::vector<Eigen::Vector3d> nrm(n), cen(n);
  std::vector<std::array<Eigen::Vector3d, 3>> vtx(n);
  std::vector<double> area(n);
  // Edges by vertex position (welded at 1 mm): meshes written with a vertex per face corner
  // have neighbourhoods too.
  std::map<std::array<long long, 3>, std::uint64_t> vid;
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> edges;  // (v0 << 32 | v1), v0 < v1
  for (std::size_t i = 0; i < n; ++i) {
    const FaceRec& fr = pts.face(tris[i]);
    std::uint64_t id[3];
    for (int k = 0; k < 3; ++k) {
      const Vec3d p{fr.v[k][0], fr.v[k][1], fr.v[k][2]};
      vtx[i][std::size_t(k)] = Eigen::Vector3d(p[0], p[1], p[2]);
      const std::array<long long, 3> q{std::llround(p[0] * 1000), std::llround(p[1] * 1000),
                                       std::llround(p[2] * 1000)};
      id[k] = vid.emplace(q, vid.size()).first->second;
    }
    const Eigen::Vector3d c = (vtx[i][1] - vtx[i][0]).cross(vtx[i][2] - vtx[i][0]);
    area[i] = 0.5 * c.norm();
    nrm[i] = area[i] > 0 ? Eigen::Vector3d(c.normalized()) : Eigen::Vector3d(0, 0, 0);
    cen[i] = (vtx[i][0] + vtx[i][1] + vtx[i][2]) / 3;
    for (int k = 0; k < 3; ++k) {
      std::uint64_t a = id[k], b = id[(k + 1) % 3];
      if (a == b) continue;
      if (a > b) std::swap(a, b);
      edges[(a << 32) | b].push_back(std::uint32_t(i));
    }
  }
  std::vector<std::vector<std::uint32_t>> adj(n);
  std::size_t shared = 0;
  for (const auto& [e, ts] : edges)
    for (std::size_t a = 0; a < ts.size(); ++a)
      for (std::size_t b = a + 1; b < ts.size(); ++b) {
        adj[ts[a]].push_back(ts[b]);
        adj[ts[b]].push_back(ts[a]);
        ++shared;
      }
  if (2 * shared < n) return -1;  // a triangle soup: no neighbourhoods to judge
  for (auto& a : adj) std::sort(a.begin(), a.end());
  const double cos_max = std::cos(kMeshPlanarAngle * M_PI / 180);
  std::vector<char> done(n, 0);
  double total = 0, planar = 0;
  for (std::size_t i = 0; i < n; ++i) total += area[i];
  std::vector<std::uint32_t> queue;
  for (std::size_t seed = 0; seed < n; ++seed) {
    if (done[seed] || area[seed] <= 0) continue;
    done[seed] = 1;
    queue.assign(1, std::uint32_t(seed));
    Eigen::Vector3d pn = nrm[seed], pc = cen[seed];
    double w = 0, fit_w = 0;
    Eigen::Vector3d s1(0, 0, 0);
    Eigen::Matrix3d s2 = Eigen::Matrix3d::Zero();
    const auto add = [&](std::size_t t) {
      for (const auto& v : vtx[t]) {
        s1 += area[t] * v;
        s2 += area[t] * v * v.transpose();
      }
      w += 3 * area[t];
    };
    add(seed);
    fit_w = w;
    double region = 0;
    for (std::size_t q = 0; q < queue.size(); ++q) {
      const std::size_t t = queue[q];
      region += area[t];
      for (std::uint32_t u : adj[t]) {
        if (done[u] || area[u] <= 0) continue;
        if (nrm[u].dot(pn) < cos_max) continue;
        bool near = true;
        for (const auto& v : vtx[u])
          near = near && std::abs((v - pc).dot(pn)) <= kMeshPlanarTolerance;
        if (!near) continue;
        done[u] = 1;
        queue.push_back(u);
        add(u);
        if (w >= 2 * fit_w && queue.size() >= 4) {  // refit the plane
          const Eigen::Vector3d mean = s1 / w;
          const Eigen::Matrix3d cov = s2 / w - mean * mean.transpose();
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
          Eigen::Vector3d nn = es.eigenvectors().col(0);
          if (nn.dot(pn) < 0) nn = -nn;
          pn = nn;
          pc = mean;
          fit_w = w;
        }
      }
    }
    if (region >= kMeshPlanarRegionArea) planar += region;
  }
  return total > 0 ? planar / total : -1;
}

// ---------------------------------------------------------------------- pass 3
// Loads the points (mesh scenes: samples and the faces meeting the box) of a box and
// returns how many (points + faces); when that is more than max_points it stops early
// (nothing kept: memory stays bounded) and returns max_points + 1.
// A region no farther than `margin` beyond the data: its grids (the ground
// model) cost its area, so a large cell (--cell-size 100000) or a park's
// footprint costs the data under it, not its size (issue 27). Never inverted.
std::array<double, 4> Splitter::within_data_reach(std::array<double, 4> box, double margin) const {
  box = {std::max(box[0], bbox_enu_.min[0] - margin), std::max(box[1], bbox_enu_.min[1] - margin),
         std::min(box[2], bbox_enu_.max[0] + margin), std::min(box[3], bbox_enu_.max[1] + margin)};
  box[2] = std::max(box[2], box[0]);
  box[3] = std::max(box[3], box[1]);
  return box;
}

std::size_t Splitter::load_region(const Spiller& spill, const std::array<double, 4>& box,
                                  RegionPoints& out, std::size_t max_points, CellJob& job) const {
  out = RegionPoints{};
  out.box = box;
  const double c = spill.cell();
  const int i0 = int(std::floor(box[0] / c)), i1 = int(std::floor(box[2] / c));
  const int j0 = int(std::floor(box[1] / c)), j1 = int(std::floor(box[3] / c));
  // The non-empty cells of the box, in (i, j) order; never more work than the spill
  // has cells, however large the box (issue 13: a box of ~10^9 cells).
  const auto in_range = [&](const CellKey& k) {
    return k.first >= i0 && k.first <= i1 && k.second >= j0 && k.second <= j1;
  };
  std::vector<CellKey> keys;
  std::uint64_t in_cells = 0;  // an upper bound of the region's points: one allocation each
  for (const auto& [k, n] : spill.counts())
    if (in_range(k)) {
      keys.push_back(k);
      in_cells += n;
    }
  const auto too_many = [&]() {
    out = RegionPoints{};
    out.box = box;
    return max_points + 1;
  };
  const auto by_id = [](std::vector<FaceRec>& v) {
    std::sort(v.begin(), v.end(), [](const FaceRec& a, const FaceRec& b) { return a.id < b.id; });
    v.erase(std::unique(v.begin(), v.end(),
                        [](const FaceRec& a, const FaceRec& b) { return a.id == b.id; }),
            v.end());
  };
  std::size_t n_faces = 0;
  if (faces_) {
    // an upper bound: the reservation is address space, pages are touched as filled
    std::uint64_t upper = 0;
    for (const auto& [k, n] : faces_->counts()) upper += in_range(k) ? n : 0;
    out.faces.reserve(std::size_t(std::min<std::uint64_t>(upper, max_points)));
    for (const auto& [k, n] : faces_->counts()) {
      if (!in_range(k)) continue;
      faces_->for_each(k, [&](const FaceRec& f) {
        const double x0 = std::min({f.v[0][0], f.v[1][0], f.v[2][0]});
        const double x1 = std::max({f.v[0][0], f.v[1][0], f.v[2][0]});
        const double y0 = std::min({f.v[0][1], f.v[1][1], f.v[2][1]});
        const double y1 = std::max({f.v[0][1], f.v[1][1], f.v[2][1]});
        if (x1 < box[0] || x0 >= box[2] || y1 < box[1] || y0 >= box[3]) return;
        out.faces.push_back(f);
      });
      if (out.faces.size() > max_points) {  // duplicates (faces over several cells) first
        by_id(out.faces);
        if (out.faces.size() > max_points) return too_many();
      }
    }
    by_id(out.faces);
    n_faces = out.faces.size();
  }
  const auto reserve = std::size_t(std::min<std::uint64_t>(in_cells, max_points));
  job.gate->hold(job.index, job.held, reserve);
  out.pos.reserve(reserve);
  if (has_normals_) out.nrm.reserve(reserve);
  if (has_colors_) out.rgb.reserve(reserve);
  if (has_classes_) out.cls.reserve(reserve);
  if (mesh_scene_) out.src.reserve(reserve);
  std::vector<SpillRec> buf(8192);
  for (const auto& cell : keys) {
    const fs::path p = spill.file(cell);
    std::FILE* f = std::fopen(p.c_str(), "rb");
    if (!f)
      throw IoError(p.string(), std::string("cannot read spill file: ") + std::strerror(errno));
    std::size_t got;
    bool over = false;
    while (!over && (got = std::fread(buf.data(), sizeof(SpillRec), buf.size(), f)) > 0) {
      for (std::size_t k = 0; k < got; ++k) {
        const SpillRec& r = buf[k];
        if (r.x < box[0] || r.x >= box[2] || r.y < box[1] || r.y >= box[3]) continue;
        if (out.pos.size() + n_faces >= max_points) {
          over = true;
          break;
        }
        out.pos.push_back({r.x, r.y, r.z});
        if (has_normals_) out.nrm.push_back({r.nx, r.ny, r.nz});
        if (has_colors_) out.rgb.push_back({r.r, r.g, r.b});
        if (has_classes_) out.cls.push_back(r.cls);
        if (mesh_scene_) out.src.push_back(r.src);
      }
    }
    const bool err = std::ferror(f);
    std::fclose(f);
    if (err) throw IoError(p.string(), "cannot read spill file");
    if (over) return too_many();
  }
  job.out.rep.max_region_points = std::max(job.out.rep.max_region_points, out.pos.size());
  return out.pos.size() + n_faces;
}

std::string Splitter::unique_id(std::string id) {
  std::string u = id;
  for (int k = 2; !ids_.insert(u).second; ++k) u = id + "-" + std::to_string(k);
  return u;
}

// A building's chunk: its record, and its points in chunk coordinates (mesh scenes: its
// claims on triangles), kept in the cell's output until merge_cell() names and writes it.
CellOutput::Chunk& Splitter::emit_chunk(const RegionPoints& pts, const CellSegmentation& seg,
                                        const std::vector<std::uint32_t>& members,
                                        const std::string& id, const std::string& source,
                                        Ring outline, CellOutput& out) const {
  CellOutput::Chunk& ch = out.chunks.emplace_back();
  ch.base_id = id;
  ChunkRecord& rec = ch.pc.rec;
  rec.source = source;
  io::BBox3 bb;
  std::vector<double> ground;
  ground.reserve(members.size());
  for (std::uint32_t k : members) {
    bb.add(pts.pos[k]);
    ground.push_back(pts.pos[k][2] - double(seg.hag[k]));
  }
  // The chunk origin on whole metres and the ground on 0.1 mm: a building's chunk is
  // the same wherever it lies (with the points snapped onto the inputs' grid below).
  rec.ground_z = std::round(median(std::move(ground)) * 1e4) / 1e4;
  rec.bbox_min = bb.min;
  rec.bbox_max = bb.max;
  rec.origin = {std::round(0.5 * (bb.min[0] + bb.max[0])),
                std::round(0.5 * (bb.min[1] + bb.max[1])), std::round(rec.ground_z)};
  if (outline.size() < 3) {
    std::vector<Vec2> xy;
    for (std::uint32_t k : members) xy.push_back({pts.pos[k][0], pts.pos[k][1]});
    outline = convex_hull(std::move(xy));
  }
  rec.outline = std::move(outline);
  rec.points = members.size();
  rec.status = Status::pending;
  if (mesh_scene_) {
    // The chunk's claims (samples per triangle) go to the cell of the triangle's
    // centroid; write_mesh_chunks() gives each triangle to the chunk with most samples.
    std::vector<std::uint64_t> tris;
    tris.reserve(members.size());
    for (std::uint32_t k : members) tris.push_back(pts.src[k]);
    std::sort(tris.begin(), tris.end());
    for (std::size_t i = 0; i < tris.size();) {
      std::size_t j = i + 1;
      while (j < tris.size() && tris[j] == tris[i]) ++j;
      ClaimRec& cr = ch.claims.emplace_back();
      cr.face = pts.face(tris[i]);
      cr.votes = static_cast<std::uint32_t>(j - i);
      i = j;
    }
    return ch;
  }
  // Chunk coordinates, snapped onto the inputs' grid, in one order (by position, then
  // class, colour, normal): the order the cells gave the points depends on what else
  // the scene holds, and the LOD stage's result on the order.
  std::vector<Vec3d> local(members.size());
  for (std::size_t i = 0; i < members.size(); ++i) {
    const Vec3d& p = pts.pos[members[i]];
    Vec3d q{p[0] - rec.origin[0], p[1] - rec.origin[1], p[2] - rec.origin[2]};
    for (std::size_t a = 0; a < 3; ++a)
      if (grid_[a] > 0) q[a] = std::round(q[a] / grid_[a]) * grid_[a];
    local[i] = q;
  }
  std::vector<std::uint32_t> order(members.size());
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    if (local[a] != local[b]) return local[a] < local[b];
    const std::uint32_t ka = members[a], kb = members[b];
    if (has_classes_ && pts.cls[ka] != pts.cls[kb]) return pts.cls[ka] < pts.cls[kb];
    if (has_colors_ && pts.rgb[ka] != pts.rgb[kb]) return pts.rgb[ka] < pts.rgb[kb];
    if (has_normals_ && pts.nrm[ka] != pts.nrm[kb]) return pts.nrm[ka] < pts.nrm[kb];
    return false;
  });
  io::PointSet& ps = ch.points;
  ps.positions.reserve(members.size());
  for (const std::uint32_t i : order) {
    const std::uint32_t k = members[i];
    ps.positions.push_back(local[i]);
    if (has_normals_) ps.normals.push_back(pts.nrm[k]);
    if (has_colors_) ps.colors.push_back(pts.rgb[k]);
    if (has_classes_) ps.classes.push_back(pts.cls[k]);
  }
  ch.write = true;
  return ch;
}

// A cell's output into the split, in cell order: each chunk named (unique_id), its file
// written, its claims filed; the cell's report lines and counters added.
void Splitter::merge_cell(CellOutput& out) {
  for (CellOutput::Chunk& ch : out.chunks) {
    ChunkRecord& rec = ch.pc.rec;
    if (ch.base_id.empty()) {  // a cluster: named by its position
      const geo::LonLatH g =
          georef_->to_geodetic(Eigen::Vector3d(ch.cluster_at[0], ch.cluster_at[1], 0));
      char key_text[64];
      std::snprintf(key_text, sizeof key_text, "%.5f,%.5f", g[0], g[1]);
      ch.base_id = "b-" + io::hash_hex(key_text, std::strlen(key_text)).substr(0, 12);
    }
    rec.id = unique_id(ch.base_id);
    if (ch.write) {
      const std::string path = (staging_->chunks() / (rec.id + ".ply")).string();
      io::PlyWriteOptions wo;
      wo.comment =
          "citylod chunk " + rec.id + " (xyz relative to the chunk origin, scene " +
          std::string(georef_->scene_frame() == geo::SceneFrame::projected ? "CRS" : "ENU") +
          " metres)";
      io::write_ply(path, ch.points, wo);
      rec.content_hash = io::hash_file(path);
      ch.points = io::PointSet{};
      ++rep_.chunks;
      if (ch.unmatched) ++rep_.unmatched_chunks;
    }
    const auto chunk = static_cast<std::uint32_t>(chunks_.size());
    for (ClaimRec& cr : ch.claims) {
      cr.chunk = chunk;
      const double cx = (cr.face.v[0][0] + cr.face.v[1][0] + cr.face.v[2][0]) / 3;
      const double cy = (cr.face.v[0][1] + cr.face.v[1][1] + cr.face.v[2][1]) / 3;
      claims_->add(key_at(cx, cy, claim_cell_), cr);
    }
    chunks_.push_back(std::move(ch.pc));
  }
  const SplitReport& r = out.rep;
  rep_.notes.insert(rep_.notes.end(), r.notes.begin(), r.notes.end());
  rep_.cluster_log.insert(rep_.cluster_log.end(), r.cluster_log.begin(), r.cluster_log.end());
  rep_.halo_growths += r.halo_growths;
  rep_.max_region_points = std::max(rep_.max_region_points, r.max_region_points);
  rep_.clusters_rejected += r.clusters_rejected;
  for (const auto& [why, n] : r.rejected_by) rep_.rejected_by[why] += n;
  rep_.footprints_with_chunk += r.footprints_with_chunk;
  rep_.footprints_inside_with_chunk += r.footprints_inside_with_chunk;
  subdivided_ += out.subdivided;
  fp_few_ += out.fp_few;
  fp_few_points_ += out.fp_few_points;
  fp_few_max_ = std::max(fp_few_max_, out.fp_few_max);
  out = CellOutput{};
}

// A region over the budget at the smallest cell: one line with the cell, the budget and
// what helps.
void Splitter::region_too_large(const CellKey& key, double size, const std::string& what) const {
  throw IoError(opt_.work_dir,
                "cell " + std::to_string(key.first) + "," + std::to_string(key.second) + " (" +
                    fmt("%.2f", size) + " m" + what + ", halo " + fmt("%.0f", opt_.halo) +
                    " m) holds more than the " + std::to_string(region_budget_points_) +
                    " points (mesh scenes: samples + faces) --memory-limit " +
                    fmt("%.0f", double(opt_.memory_limit) / 1048576) +
                    "M allows, even at the smallest cell size: raise --memory-limit (or lower "
                    "--halo)");
}

// Clusters: owned by the cell holding their centroid; the halo doubles while an
// owned building touches the edge of what was loaded (so it is never cut). A cell whose
// region exceeds the budget is processed as its four quarters (key_at at size / 2).
void Splitter::process_cell_clusters(const Spiller& spill, const CellKey& key, double size,
                                     bool unmatched, CellJob& job) {
  SplitReport& rep = job.out.rep;
  const double c = size;
  const double cx0 = key.first * c, cy0 = key.second * c, cx1 = cx0 + c, cy1 = cy0 + c;
  // Exact ownership: the cell holding the cluster's anchor point.
  auto owns = [&](const Cluster& cl) { return key_at(cl.anchor[0], cl.anchor[1], c) == key; };
  double halo = opt_.halo;
  RegionPoints pts;
  CellSegmentation seg;
  for (;;) {
    const std::array<double, 4> box =
        within_data_reach({cx0 - halo, cy0 - halo, cx1 + halo, cy1 + halo}, opt_.halo);
    const std::size_t n = load_region(spill, box, pts, region_budget_points_, job);
    if (unmatched) drop_footprint_points(pts, *job.fp);
    if (n > region_budget_points_) {
      if (halo > opt_.halo) {  // keep the previous (smaller) result
        rep.notes.push_back("cell " + std::to_string(key.first) + "," + std::to_string(key.second) +
                            ": a building larger than the halo was cut (memory limit)");
        const std::array<double, 4> prev = within_data_reach(
            {cx0 - halo / 2, cy0 - halo / 2, cx1 + halo / 2, cy1 + halo / 2}, opt_.halo);
        load_region(spill, prev, pts, ~std::size_t(0), job);
        if (unmatched) drop_footprint_points(pts, *job.fp);
        seg = segment_cell(pts.pos, pts.cls, mode_, opt_.seg, prev, true);
        break;
      }
      // Nothing of its own to process: skip. Else quarters, down to kMinSplitCell.
      RegionPoints own;
      if (load_region(spill, {cx0, cy0, cx1, cy1}, own, 0, job) == 0) return;
      if (!(c > kMinSplitCell)) region_too_large(key, c, "");
      if (c == cell_) ++job.out.subdivided;
      for (int di = 0; di < 2; ++di)
        for (int dj = 0; dj < 2; ++dj)
          process_cell_clusters(spill, {2 * key.first + di, 2 * key.second + dj}, c / 2, unmatched,
                                job);
      return;
    }
    seg = segment_cell(pts.pos, pts.cls, mode_, opt_.seg, box, true);
    // Does an owned building touch an edge of the region behind which there is data?
    const double tol = opt_.seg.cluster_tolerance;
    bool truncated = false;
    for (const auto& cl : seg.clusters) {
      if (!cl.building) continue;
      if (!owns(cl)) continue;
      for (std::uint32_t k : cl.members) {
        const Vec3d& p = pts.pos[k];
        if ((p[0] - box[0] < tol && box[0] > bbox_enu_.min[0]) ||
            (box[2] - p[0] < tol && box[2] < bbox_enu_.max[0]) ||
            (p[1] - box[1] < tol && box[1] > bbox_enu_.min[1]) ||
            (box[3] - p[1] < tol && box[3] < bbox_enu_.max[1])) {
          truncated = true;
          break;
        }
      }
      if (truncated) break;
    }
    if (!truncated || halo >= opt_.max_halo) {
      if (truncated)
        rep.notes.push_back("cell " + std::to_string(key.first) + "," + std::to_string(key.second) +
                            ": a building larger than --max-halo was cut");
      break;
    }
    halo = std::min(2 * halo, opt_.max_halo);
    ++rep.halo_growths;
  }
  for (auto& cl : seg.clusters) {
    if (!owns(cl)) continue;
    double planar_share = -1;  // mesh scenes: share of the cluster's area in large planar faces
    if (mesh_scene_ && cl.building) {
      std::vector<std::uint64_t> tris;
      tris.reserve(cl.members.size());
      for (std::uint32_t k : cl.members) tris.push_back(pts.src[k]);
      planar_share = mesh_planar_share(std::move(tris), pts);
      if (planar_share >= 0 && planar_share < kMeshMinPlanarShare) {
        cl.building = false;
        char why[160];
        std::snprintf(why, sizeof why,
                      "vegetation (mesh: %.0f%% of its area in planar faces of >= %.0f m2)",
                      100 * planar_share, kMeshPlanarRegionArea);
        cl.reject_reason = why;
      }
    }
    {
      char line[320];
      std::snprintf(line, sizeof line,
                    "cluster at (%.1f, %.1f): %zu points, area %.1f m2, width %.1f m, height %.1f "
                    "m, foliage ratio %.2f, "
                    "planar %.2f, mesh planar faces %.2f: %s",
                    cl.centroid[0], cl.centroid[1], cl.members.size(), cl.area, cl.width, cl.height,
                    cl.vegetation_ratio, cl.planar_fraction, planar_share,
                    cl.building ? "building" : cl.reject_reason.c_str());
      rep.cluster_log.push_back(line);
    }
    if (!cl.building) {
      ++rep.clusters_rejected;
      ++rep.rejected_by[cl.reject_reason.substr(0, cl.reject_reason.find(' '))];
      continue;
    }
    // named by its position at the merge (the georeference is not shared by workers)
    CellOutput::Chunk& ch =
        emit_chunk(pts, seg, cl.members, "", unmatched ? "cluster (no footprint)" : "cluster",
                   cl.hull, job.out);
    ch.cluster_at = {cl.centroid[0], cl.centroid[1]};
    ch.unmatched = unmatched;
  }
}

// Footprints: owned by the cell holding their centroid; a point goes to the
// footprint containing it, else to the nearest within the buffer.
void Splitter::process_cell_footprints(const Spiller& spill, const CellKey& key, double size,
                                       const std::vector<std::size_t>& owned, CellJob& job) {
  CellOutput& out = job.out;
  const double c = size;
  std::array<double, 4> box{key.first * c - opt_.halo, key.second * c - opt_.halo,
                            (key.first + 1) * c + opt_.halo, (key.second + 1) * c + opt_.halo};
  const double margin = opt_.footprint_buffer + opt_.halo;
  for (std::size_t i : owned) {
    const auto& b = fps_[i].bbox;
    box = {std::min(box[0], b[0] - margin), std::min(box[1], b[1] - margin),
           std::max(box[2], b[2] + margin), std::max(box[3], b[3] + margin)};
  }
  // ... but no farther than the data reach: the region's grids (the ground
  // model) cost its area, and a footprint of a park or an airport must cost the
  // data under it, not its size (issue 27: a 6 km square over a 72 m tile).
  box = within_data_reach(box, margin);
  RegionPoints pts;
  const std::size_t n = load_region(spill, box, pts, region_budget_points_, job);
  if (n > region_budget_points_) {
    // Quarters (the footprints by the quarter holding their centroid), down to kMinSplitCell.
    if (!(c > kMinSplitCell))
      region_too_large(key, c,
                       owned.size() == 1 ? " with footprint '" + fps_[owned[0]].id + "'" : "");
    if (c == cell_) ++out.subdivided;
    std::map<CellKey, std::vector<std::size_t>> parts;
    for (std::size_t i : owned) {
      const Vec2 ce = fps_[i].centroid();
      parts[key_at(ce[0], ce[1], c / 2)].push_back(i);
    }
    for (const auto& [k, v] : parts) process_cell_footprints(spill, k, c / 2, v, job);
    return;
  }
  const CellSegmentation seg = segment_cell(pts.pos, pts.cls, mode_, opt_.seg, box, false);
  std::map<std::size_t, std::vector<std::uint32_t>> members;
  const std::set<std::size_t> mine(owned.begin(), owned.end());
  const bool have_cls = mode_ != ClassMode::none;
  if (mesh_scene_) mesh_footprint_members(pts, seg, mine, members);
  for (std::size_t k = 0; !mesh_scene_ && k < pts.pos.size(); ++k) {
    if (mode_ == ClassMode::buildings) {
      if (pts.cls[k] != 6) continue;
    } else {
      if (seg.ground[k] || seg.hag[k] < opt_.seg.ground_tolerance) continue;
      if (have_cls && non_building_class(pts.cls[k])) continue;
      if (seg.foliage[k] && seg.hag[k] >= opt_.seg.min_height) continue;
    }
    const std::size_t best = footprint_of({pts.pos[k][0], pts.pos[k][1]}, *job.fp);
    if (best != SIZE_MAX && mine.count(best))
      members[best].push_back(static_cast<std::uint32_t>(k));
  }
  for (std::size_t i : owned) {
    const auto it = members.find(i);
    const std::size_t count = it == members.end() ? 0 : it->second.size();
    if (count < static_cast<std::size_t>(std::max(1, opt_.min_footprint_points))) {
      CellOutput::Chunk& ch = out.chunks.emplace_back();
      ch.base_id = "fp-" + sanitize_id(fps_[i].id);
      PendingChunk& pc = ch.pc;
      pc.rec.source = "footprint:" + fps_[i].id;
      pc.rec.status = Status::skipped;
      if (count > 0) {
        ++out.fp_few;
        out.fp_few_points += count;
        out.fp_few_max = std::max(out.fp_few_max, count);
      }
      pc.rec.reason =
          count == 0 ? "no building points inside the footprint"
                     : "only " + std::to_string(count) + " building points inside the footprint";
      const Ring& r = fps_[i].main_ring();
      pc.rec.outline = r;
      const Vec2 ce = fps_[i].centroid();
      pc.rec.origin = {ce[0], ce[1], 0};
      pc.rec.bbox_min = {fps_[i].bbox[0], fps_[i].bbox[1], 0};
      pc.rec.bbox_max = {fps_[i].bbox[2], fps_[i].bbox[3], 0};
      pc.rec.attributes = fps_[i].attributes;
      continue;
    }
    ++out.rep.footprints_with_chunk;
    if (fp_inside_[i]) ++out.rep.footprints_inside_with_chunk;
    emit_chunk(pts, seg, it->second, "fp-" + sanitize_id(fps_[i].id), "footprint:" + fps_[i].id,
               fps_[i].main_ring(), out)
        .pc.rec.attributes = fps_[i].attributes;
  }
}

// Hands the heap's free memory back to the system between cells: glibc keeps up to its
// trim threshold free, and that threshold grows with the largest block freed so far (the
// ingest's batches), so a cell's freed regions stayed resident through the next cells.
void release_free_memory() {
#ifdef __GLIBC__
  malloc_trim(0);
#endif
}

void Splitter::pass3_cells(const Spiller& spill) {
  std::vector<CellKey> cells;
  if (opt_.footprints.empty()) {
    for (const auto& [k, n] : spill.counts()) cells.push_back(k);
  } else {
    for (const auto& [k, v] : fp_owned_) cells.push_back(k);
  }
  rep_.cells = spill.counts().size();
  const bool segment =
      !opt_.footprints.empty() && opt_.unmatched == SplitOptions::Unmatched::segment;
  const double total = double(cells.size() + (segment ? spill.counts().size() : 0));
  run_cells(cells.size(), 0, total, "segment", [&](CellJob& job) {
    const CellKey& key = cells[job.index];
    if (opt_.footprints.empty())
      process_cell_clusters(spill, key, cell_, false, job);
    else
      process_cell_footprints(spill, key, cell_, fp_owned_.at(key), job);
  });
  if (subdivided_ > 0)
    rep_.notes.push_back(std::to_string(subdivided_) +
                         " cells processed in quarters to fit --memory-limit");
  if (opt_.footprints.empty()) return;
  count_unmatched(spill);
  if (!segment) return;
  std::vector<CellKey> all;
  for (const auto& [k, n] : spill.counts()) all.push_back(k);
  run_cells(all.size(), cells.size(), total, "segment unmatched",
            [&](CellJob& job) { process_cell_clusters(spill, all[job.index], cell_, true, job); });
}

// Cells on the split's threads, merged in cell order: a worker that finishes ahead waits
// with its output. Regions held at once stay within the region budget (RegionGate). The
// first failure in cell order is rethrown once all have stopped (run_workers: no OpenMP).
template <class Process>
void Splitter::run_cells(std::size_t n, std::size_t progress_from, double progress_total,
                         const char* stage, Process&& process) {
  RegionGate gate(region_budget_points_);
  std::atomic<std::size_t> next{0};
  std::atomic<bool> failed{false};
  std::mutex mu;
  std::condition_variable merged_cv;
  std::size_t merged = 0;  // cells merged so far: the next to merge
  std::exception_ptr failure;
  const auto worker = [&]() {
    FpCache fp;
    for (std::size_t i; (i = next++) < n;) {
      CellJob job;
      job.index = i;
      job.gate = &gate;
      job.fp = &fp;
      std::exception_ptr err;
      if (!failed) {
        try {
          process(job);
        } catch (...) {
          err = std::current_exception();
          failed = true;
        }
      }
      std::unique_lock<std::mutex> lock(mu);
      merged_cv.wait(lock, [&] { return merged == i; });
      if (err && !failure) failure = err;
      if (!failure) {
        try {
          merge_cell(job.out);
          stages_.report(0.5, 0.97, double(progress_from + i + 1) / progress_total, stage);
        } catch (...) {
          failure = std::current_exception();
          failed = true;
        }
      }
      ++merged;
      lock.unlock();
      gate.done(i, job.held);
      merged_cv.notify_all();
      release_free_memory();
    }
  };
  run_workers(opt_.threads, n, worker);
  if (failure) std::rethrow_exception(failure);
}

// Building points (class 6) outside every footprint (+ buffer), each counted once:
// the spill file of a cell holds exactly its points.
void Splitter::count_unmatched(const Spiller& spill) {
  if (mode_ != ClassMode::buildings) {
    rep_.notes.push_back(
        "no building class in the input: points outside the footprints are not counted");
    return;
  }
  // Each cell's file on the split's threads (a footprint cache per worker), summed in order.
  std::vector<CellKey> cells;
  for (const auto& [k, n] : spill.counts()) cells.push_back(k);
  std::vector<std::int64_t> per_cell(cells.size(), 0);
  std::atomic<std::size_t> next{0};
  std::exception_ptr failure;
  std::mutex mu;
  const auto worker = [&]() {
    FpCache fp;
    std::vector<SpillRec> buf(8192);
    for (std::size_t c; (c = next++) < cells.size();) {
      try {
        const fs::path p = spill.file(cells[c]);
        std::FILE* f = std::fopen(p.c_str(), "rb");
        if (!f)
          throw IoError(p.string(), std::string("cannot read spill file: ") + std::strerror(errno));
        std::size_t got;
        while ((got = std::fread(buf.data(), sizeof(SpillRec), buf.size(), f)) > 0)
          for (std::size_t j = 0; j < got; ++j)
            if (buf[j].cls == 6 && footprint_of({buf[j].x, buf[j].y}, fp) == SIZE_MAX)
              ++per_cell[c];
        const bool err = std::ferror(f);
        std::fclose(f);
        if (err) throw IoError(p.string(), "cannot read spill file");
      } catch (...) {
        const std::lock_guard<std::mutex> lock(mu);
        if (!failure) failure = std::current_exception();
      }
    }
  };
  run_workers(opt_.threads, cells.size(), worker);
  if (failure) std::rethrow_exception(failure);
  std::int64_t out = 0;
  for (const std::int64_t n : per_cell) out += n;
  rep_.building_points = std::int64_t(class_hist_[6]);
  rep_.unmatched_points = out;
  char b[256];
  std::snprintf(b, sizeof b,
                "%lld of %lld building (class 6) points lie outside every footprint (%.1f %%): %s",
                static_cast<long long>(out), static_cast<long long>(class_hist_[6]),
                class_hist_[6] ? 100.0 * double(out) / double(class_hist_[6]) : 0.0,
                opt_.unmatched == SplitOptions::Unmatched::segment
                    ? "clustered into buildings without footprint (--unmatched segment)"
                    : "dropped (--unmatched drop)");
  rep_.notes.push_back(b);
}

// --unmatched segment: the points of a region that belong to a footprint are taken
// out before clustering (they are the footprints' buildings).
void Splitter::drop_footprint_points(RegionPoints& pts, FpCache& fp) const {
  std::size_t w = 0;
  for (std::size_t k = 0; k < pts.pos.size(); ++k) {
    if (footprint_of({pts.pos[k][0], pts.pos[k][1]}, fp) != SIZE_MAX) continue;
    pts.pos[w] = pts.pos[k];
    if (!pts.nrm.empty()) pts.nrm[w] = pts.nrm[k];
    if (!pts.rgb.empty()) pts.rgb[w] = pts.rgb[k];
    if (!pts.cls.empty()) pts.cls[w] = pts.cls[k];
    if (!pts.src.empty()) pts.src[w] = pts.src[k];
    ++w;
  }
  pts.pos.resize(w);
  if (!pts.nrm.empty()) pts.nrm.resize(w);
  if (!pts.rgb.empty()) pts.rgb.resize(w);
  if (!pts.cls.empty()) pts.cls.resize(w);
  if (!pts.src.empty()) pts.src.resize(w);
}

// Mesh scenes: a triangle goes to the chunk holding most of its samples (ties to the
// first chunk). The claims are resolved cell by cell and the winners appended to a file
// per chunk; each chunk is then written from its file alone (triangles in input order,
// vertices in order of first use): memory holds one cell's claims or one chunk.
void Splitter::write_mesh_chunks() {
  claims_->flush();
  CellFiles<FaceRec> won(staging_->faces(), "won_", 1u << 16);
  for (const auto& [k, n] : claims_->counts()) {
    std::vector<ClaimRec> cl = claims_->read(k);
    std::sort(cl.begin(), cl.end(), [](const ClaimRec& a, const ClaimRec& b) {
      if (a.face.id != b.face.id) return a.face.id < b.face.id;
      if (a.votes != b.votes) return a.votes > b.votes;
      return a.chunk < b.chunk;
    });
    for (std::size_t i = 0; i < cl.size(); ++i)
      if (i == 0 || cl[i].face.id != cl[i - 1].face.id) won.add({int(cl[i].chunk), 0}, cl[i].face);
    won.flush();
  }
  for (std::size_t c = 0; c < chunks_.size(); ++c) {
    ChunkRecord& rec = chunks_[c].rec;
    if (rec.status != Status::pending) continue;
    std::vector<FaceRec> tris = won.read({int(c), 0});
    if (tris.empty()) {
      rec.status = Status::skipped;
      rec.reason = "no triangles assigned";
      continue;
    }
    std::sort(tris.begin(), tris.end(),
              [](const FaceRec& a, const FaceRec& b) { return a.id < b.id; });
    io::TriangleMesh out;
    std::unordered_map<std::uint64_t, std::uint32_t> remap;
    io::BBox3 bb;
    for (const FaceRec& f : tris) {
      std::array<std::uint32_t, 3> nt{};
      for (std::size_t v = 0; v < 3; ++v) {
        auto [it, fresh] = remap.emplace(f.vid[v], static_cast<std::uint32_t>(out.vertices.size()));
        if (fresh) {
          const Vec3d p{f.v[v][0], f.v[v][1], f.v[v][2]};
          bb.add(p);
          out.vertices.push_back(p);
          if (has_normals_) out.normals.push_back({f.n[v][0], f.n[v][1], f.n[v][2]});
          if (has_colors_) out.colors.push_back({f.rgb[v][0], f.rgb[v][1], f.rgb[v][2]});
        }
        nt[v] = it->second;
      }
      out.triangles.push_back(nt);
    }
    {
      std::error_code ec;
      fs::remove(won.file({int(c), 0}), ec);
    }
    rec.bbox_min = bb.min;
    rec.bbox_max = bb.max;
    rec.origin = {std::round(0.5 * (bb.min[0] + bb.max[0])),
                  std::round(0.5 * (bb.min[1] + bb.max[1])), std::round(rec.ground_z)};
    for (auto& v : out.vertices)
      v = {v[0] - rec.origin[0], v[1] - rec.origin[1], v[2] - rec.origin[2]};
    rec.points = out.vertices.size();
    rec.triangles = out.triangles.size();
    const std::string path = (staging_->chunks() / (rec.id + ".ply")).string();
    io::write_ply(path, out);
    rec.content_hash = io::hash_file(path);
    ++rep_.chunks;
  }
  staging_->drop_faces();
}

SplitReport Splitter::run() {
  const auto t0 = std::chrono::steady_clock::now();
  opt_.validate();

  // Up to date? Compare inputs (absolute paths), their sizes/mtimes and the options.
  std::vector<std::string> abs_inputs;
  std::string canonical = opt_.canonical();
  for (const auto& p : expand_inputs(opt_.inputs)) {
    InputInfo in;
    in.path = p;
    in.abs = fs::absolute(p).lexically_normal().string();
    abs_inputs.push_back(in.abs);
    canonical += ";input=" + in.abs + ":" + fingerprint(p);
    read_sidecars(in, sidecars_);
    if (!opt_.offset.empty()) in.offset = *parse_triple(opt_.offset);
    inputs_.push_back(std::move(in));
  }
  for (const auto& sc : sidecars_) canonical += ";sidecar=" + sc + ":" + fingerprint(sc);
  // A database ("PG:...") or a directory cannot be fingerprinted: never up to date.
  bool versioned = true;
  if (!opt_.footprints.empty()) {
    std::error_code ec;
    if (fs::is_regular_file(opt_.footprints, ec))
      canonical += ";footprints_file=" + fingerprint(opt_.footprints);
    else
      versioned = false;
  }
  if (versioned && !opt_.force && fs::exists(manifest_path(opt_.work_dir))) {
    try {
      const Manifest old = read_manifest(opt_.work_dir);
      bool ok = old.scene.inputs == abs_inputs && old.scene.options == canonical;
      for (const auto& c : old.chunks)
        if (ok && !c.skipped() && !fs::exists(chunk_path(opt_.work_dir, c.id))) ok = false;
      if (ok) {
        rep_.up_to_date = true;
        rep_.crs = old.scene.crs.size() > 40 ? old.scene.crs.substr(0, 37) + "..." : old.scene.crs;
        rep_.origin_lon = old.scene.origin_lon;
        rep_.origin_lat = old.scene.origin_lat;
        rep_.origin_h = old.scene.origin_h;
        for (const auto& c : old.chunks) rep_.chunks += !c.skipped() ? 1 : 0;
        rep_.notes = old.scene.notes;
        rep_.vertical = old.scene.vertical;
        rep_.building_points = old.scene.building_points;
        rep_.unmatched_points = old.scene.unmatched_points;
        for (const auto& c : old.chunks)
          rep_.unmatched_chunks += !c.skipped() && c.source == "cluster (no footprint)" ? 1 : 0;
        return rep_;
      }
    } catch (const IoError&) {
      // unreadable manifest: split again
    }
  }

  if (!opt_.footprints.empty()) read_footprints();
  pass1_headers();
  georeference();
  choose_cell_size();
  const auto& o = georef_->frame().origin();
  rep_.origin_lon = o[0];
  rep_.origin_lat = o[1];
  rep_.origin_h = o[2];

  staging_ = std::make_unique<Staging>(opt_.work_dir);
  // The spill buffer only batches writes: a quarter of the budget, at most 32 MiB (mesh
  // scenes 8 MiB: a tile, its face records and the regions' faces share the budget; their
  // chunks are written by triangle, whatever the order of the samples in a cell).
  const double spill_bytes =
      std::min(0.25 * double(opt_.memory_limit), (mesh_scene_ ? 8.0 : 32.0) * 1024 * 1024);
  const std::size_t spill_budget = static_cast<std::size_t>(spill_bytes / sizeof(SpillRec));
  Spiller spill(staging_->spill(), cell_, spill_budget);
  if (mesh_scene_) {
    // face records and claims: 8 MiB buffers each
    faces_ =
        std::make_unique<CellFiles<FaceRec>>(staging_->faces(), "f_", (8u << 20) / sizeof(FaceRec));
    claims_ = std::make_unique<CellFiles<ClaimRec>>(staging_->faces(), "c_",
                                                    (8u << 20) / sizeof(ClaimRec));
  }
  pass2_spill(spill);
  if (!opt_.footprints.empty()) load_footprints();
  pass3_cells(spill);
  staging_->drop_spill();
  if (mesh_scene_) write_mesh_chunks();
  if (!opt_.footprints.empty() && rep_.chunks == 0) {
    const std::string n = std::to_string(rep_.footprints_in_scene);
    // Building points inside footprints, but too few in each: footprints smaller
    // than buildings (pieces of a footprint, a grid of cells), not another area.
    if (fp_few_ > 0)
      throw IoError(fp_source_, "none of its " + n + " footprints over the data holds " +
                                    std::to_string(opt_.min_footprint_points) +
                                    " building points: " + std::to_string(fp_few_) +
                                    " hold some (" + std::to_string(fp_few_points_) +
                                    " in all, at most " + std::to_string(fp_few_max_) +
                                    " in one): footprints much smaller than the buildings?");
    throw IoError(fp_source_, "none of its " + n +
                                  " footprints over the data holds building points (all "
                                  "skipped): wrong CRS, or footprints of another area?");
  }
  stages_.report(0.97, 1.0, 0.5, "manifest");

  Manifest m;
  m.scene.crs = crs_spec_;
  m.scene.projected_frame = georef_->scene_frame() == geo::SceneFrame::projected;
  const auto& oc = georef_->origin_crs();
  m.scene.origin_crs = {oc[0], oc[1], oc[2]};
  m.scene.origin_lon = o[0];
  m.scene.origin_lat = o[1];
  m.scene.origin_h = o[2];
  m.scene.inputs = abs_inputs;
  m.scene.options = canonical;
  m.scene.notes = rep_.notes;
  m.scene.vertical = rep_.vertical;
  m.scene.building_points = rep_.building_points;
  m.scene.unmatched_points = rep_.unmatched_points;
  for (auto& c : chunks_) m.chunks.push_back(std::move(c.rec));
  staging_->commit(m);
  stages_.report(0.97, 1.0, 1.0, "done");
  rep_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return rep_;
}

}  // namespace

SplitReport split_scene(const SplitOptions& options, const ProgressFn& progress) {
  Splitter s(options, progress);
  SplitReport r = s.run();
  notify_finished(progress, "split");
  return r;
}

}  // namespace citylod::tiler
