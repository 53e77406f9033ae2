// The split's spill storage (private to tiler/src/split): the cell grid's keys, the
// records spilled to disk (points, mesh triangles, chunk claims), the per-cell files
// that hold them (CellFiles, Spiller) and the work directory transaction (Staging).
// Implementation: spill.cpp.
#pragma once

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <numeric>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "citylod/io/atomic_file.hpp"
#include "citylod/io/error.hpp"
#include "citylod/tiler/workdir.hpp"

namespace citylod::tiler::split_detail {

namespace fs = std::filesystem;
using io::IoError;

using CellKey = std::pair<int, int>;
/// The cell of (x, y) in a grid of cells of `size` (cell_ / 2^depth: halving is exact, so
/// a point's quarter cell lies inside its cell).
inline CellKey key_at(double x, double y, double size) {
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
  /// `buf` out by cell, each cell's records in arrival order (spill.cpp).
  void write(const std::vector<SpillRec>& buf);

  CellFiles<SpillRec> files_;
  double cell_;
  std::size_t budget_;
  std::vector<SpillRec> buf_;      ///< filling
  std::vector<SpillRec> writing_;  ///< being written by writer_
  std::thread writer_;
  std::exception_ptr error_;
};

/// The work directory transaction: a staging dir inside WORK, removed unless committed.
class Staging {
 public:
  explicit Staging(const fs::path& work);
  ~Staging();
  Staging(const Staging&) = delete;
  Staging& operator=(const Staging&) = delete;

  fs::path spill() const { return split_spill_dir(dir_.string()); }
  /// A scratch file of the staging directory (removed with it).
  fs::path scratch(const std::string& name) const { return dir_ / name; }
  fs::path chunks() const { return chunks_dir(dir_.string()); }  ///< becomes WORK/chunks
  void drop_spill() {
    std::error_code ec;
    fs::remove_all(spill(), ec);
  }
  /// Mesh scenes: face records, chunk claims and won triangles.
  fs::path faces() const { return split_faces_dir(dir_.string()); }
  void drop_faces() {
    std::error_code ec;
    fs::remove_all(faces(), ec);
  }

  /// Swaps the staged chunks in and writes the manifest; restores the old state on failure.
  void commit(const Manifest& m);

 private:
  void remove_stale();

  fs::path work_, dir_;
  std::unique_ptr<io::StagedDirectory> staged_;
  bool created_work_ = false, committed_ = false;
};

}  // namespace citylod::tiler::split_detail
