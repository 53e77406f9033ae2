// What the split's files share (private to tiler/src/split): the Splitter class, whose
// passes are defined across them, and the types its passes hand each other. One job a
// file, in the order a split runs:
//   split_options.cpp    SplitOptions (validate, canonical), parse_memory_size
//   split_inputs.cpp     inputs (folders expanded), sidecars (.prj, metadata.xml), pass 1
//   split_georef.cpp     the CRS, the scene frame and the inputs' grid; the memory plan
//   split_ingest.cpp     pass 2: points and mesh samples spilled by cell (spill.hpp)
//   split_footprints.cpp footprints read and placed; which footprint a point or face is in
//   split_cells.cpp      pass 3: regions loaded, segmented and cut into chunks, on threads
//   split_chunks.cpp     chunks made, merged in cell order, written (mesh chunks last)
//   split.cpp            Splitter::run (up-to-date check, the passes, manifest), split_scene
// and, under them, spill.hpp / spill.cpp: the spill storage (CellFiles, Spiller, Staging).
#pragma once

#include <algorithm>
#include <array>
#include <climits>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Geometry>

#include "citylod/geo/georef.hpp"
#include "citylod/io/reader.hpp"
#include "citylod/tiler/split.hpp"
#include "citylod/tiler/workdir.hpp"
#include "spill.hpp"
#include "vertex_store.hpp"

namespace citylod::tiler::split_detail {

using io::Vec3d;

// ---------------------------------------------------------------------- helpers
inline std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

/// "X,Y[,Z]" (commas or blanks) -> numbers; nullopt when malformed or not finite.
std::optional<io::Vec3d> parse_triple(const std::string& s);

/// "<size>:<mtime ns>" of a file; IoError when it does not exist.
std::string fingerprint(const std::string& path);

// Cells are halved (the initial grid from the average density, then a region that
// exceeds the budget processed as quarters) while larger than this: the grids of all
// memory limits nest, so a limit that passes is passed by every higher one.
constexpr double kMinSplitCell = 10;

// Meshes without footprints: a cluster with less than kMeshMinPlanarShare of its area in
// planar regions of >= kMeshPlanarRegionArea is vegetation (Splitter::mesh_planar_share).
constexpr double kMeshPlanarRegionArea = 6;  ///< m^2
constexpr double kMeshMinPlanarShare = 0.2;

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

/// A folder input stands for the scene files under it (any depth, sorted by path).
std::vector<std::string> expand_inputs(const std::vector<std::string>& inputs);
/// Sidecars of an input: FILE.prj beside it (CRS as WKT), else a ContextCapture
/// metadata.xml in its folder or the two above it (<SRS> and <SRSOrigin>). Records
/// the sidecar files used in `used` (for the up-to-date check).
void read_sidecars(InputInfo& in, std::set<std::string>& used);
Eigen::AlignedBox3d to_eigen(const io::BBox3& b);
/// The first input's path (+ how many more), for messages.
std::string inputs_label(const std::vector<InputInfo>& in);

/// A chunk being assembled, before the file is written.
struct PendingChunk {
  ChunkRecord rec;
};

/// footprint_of's answer rasters (by 50 m bucket) and the queries of the buckets that
/// have none yet: one per pass-3 worker (the answers do not depend on it).
struct FpCache {
  std::unordered_map<CellKey, std::vector<std::int32_t>, CellKeyHash> raster;
  std::unordered_map<CellKey, std::uint32_t, CellKeyHash> queries;
  // The bucket asked last (a region's points come in runs from one place): its
  // candidates (null: no footprint near) and its raster (null: none built yet).
  CellKey last{INT_MIN, INT_MIN};
  const std::vector<std::size_t>* candidates = nullptr;
  const std::vector<std::int32_t>* last_raster = nullptr;
};

/// What pass 3 makes of one cell, merged into the split in cell order (merge_cell): the
/// chunks' ids, their order, their files and the report do not depend on which worker
/// ran the cell, nor when.
struct CellOutput {
  struct Chunk {
    PendingChunk pc;
    std::string base_id;           ///< before unique_id; "" = from the cluster's centroid
    bool named = false;            ///< pc.rec.id is final (footprints: named before pass 3)
    bool written = false;          ///< its file written by the worker (content_hash set)
    Vec2 cluster_at{0, 0};         ///< a cluster's centroid (scene frame): its id
    bool write = false;            ///< a point chunk: `points` to WORK/chunks/<id>.ply
    bool unmatched = false;        ///< --unmatched segment: a building without footprint
    io::PointSet points;           ///< chunk coordinates, in the chunk's order
    std::vector<ClaimRec> claims;  ///< mesh scenes (the chunk index set by the merge)
  };
  std::vector<Chunk> chunks;
  SplitReport rep;  ///< this cell's notes, cluster lines and counters
  /// Spill cells whose building points outside every footprint this cell counted.
  std::vector<std::pair<CellKey, std::int64_t>> unmatched;
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

// ====================================================================== the splitter
class Splitter {
 public:
  Splitter(const SplitOptions& o, const ProgressFn& progress) : opt_(o), stages_(progress) {}

  SplitReport run();

 private:
  // split_inputs.cpp
  void pass1_headers();

  // split_georef.cpp
  void georeference();
  void choose_cell_size();

  // split_ingest.cpp (pass 2)
  void pass2_spill(Spiller& spill);
  void ingest_points(const InputInfo& in, double a, double b, Spiller& spill, io::BBox3& seen_crs);
  void ingest_mesh(std::size_t input, double a, double b, Spiller& spill, io::BBox3& seen_crs);
  void read_mesh_vertices(const InputInfo& in, io::MeshReader& reader, VertexStore& mv,
                          io::BBox3& seen_crs);
  std::uint64_t ingest_mesh_faces(std::size_t input, double a, double b, io::MeshReader& reader,
                                  const VertexStore& mv, Spiller& spill, double& up);
  void to_scene(const InputInfo& in, std::vector<Vec3d>& v, io::BBox3& seen_crs);
  SpillRec spill_rec(const io::PointSet& batch, std::size_t k);
  void spill_points(const InputInfo& in, const io::PointSet& batch, std::uint64_t first_src,
                    Spiller& spill);
  void spill_samples(const InputInfo& in, io::PointSet& batch,
                     const std::vector<std::uint64_t>& refs, std::size_t input, Spiller& spill);
  /// A streamed mesh triangle (its vertex ids and vertices) to the face files of the
  /// cells its xy box meets.
  void spill_face(const std::array<std::uint32_t, 3>& tri,
                  const std::array<VertexStore::Vertex, 3>& v, std::uint64_t t, std::size_t input);
  void check_area_of_use(const io::BBox3& seen_crs, const std::string& label);
  void choose_class_mode();

  // split_footprints.cpp
  void read_footprints();
  void load_footprints();
  std::size_t footprint_of(const Vec2& q, FpCache& fp) const;
  std::size_t mesh_footprint_of(const FaceRec& f, bool above_ground) const;
  double mesh_planar_share(std::vector<std::uint64_t> tris, const RegionPoints& pts) const;
  void mesh_footprint_members(const RegionPoints& pts, const CellSegmentation& seg,
                              const std::set<std::size_t>& mine,
                              std::map<std::size_t, std::vector<std::uint32_t>>& members) const;

  // split_cells.cpp (pass 3)
  void pass3_cells(const Spiller& spill);
  /// Runs `process(job)` for cells 0..n-1 on the split's threads and merges each
  /// cell's output in order.
  template <class Process>
  void run_cells(std::size_t n, std::size_t progress_from, double progress_total, const char* stage,
                 Process&& process);
  void process_cell_clusters(const Spiller& spill, const CellKey& key, double size, bool unmatched,
                             CellJob& job);
  void process_cell_footprints(const Spiller& spill, const CellKey& key, double size,
                               const std::vector<std::size_t>& owned, CellJob& job);
  void count_unmatched(const Spiller& spill);
  void drop_footprint_points(RegionPoints& pts, FpCache& fp) const;
  [[noreturn]] void region_too_large(const CellKey& key, double size,
                                     const std::string& what) const;
  std::array<double, 4> within_data_reach(std::array<double, 4> box, double margin) const;
  std::size_t load_region(const Spiller& spill, const std::array<double, 4>& box, RegionPoints& out,
                          std::size_t max_points, CellJob& job) const;

  // split_chunks.cpp
  CellOutput::Chunk& emit_chunk(const RegionPoints& pts, const CellSegmentation& seg,
                                const std::vector<std::uint32_t>& members, const std::string& id,
                                const std::string& source, Ring outline, CellOutput& out) const;
  std::optional<std::vector<std::uint64_t>> grid_keys(const std::vector<Vec3d>& local) const;
  void write_chunk_file(CellOutput::Chunk& ch) const;
  void merge_cell(CellOutput& out);
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
  std::map<CellKey, std::int64_t> unmatched_by_cell_;  // counted in pass 3
  std::vector<std::string> fp_chunk_id_;  // each footprint's chunk id (unique, index order)
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

}  // namespace citylod::tiler::split_detail
