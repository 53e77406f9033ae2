// Pass 3 of the split: the cells on the split's threads, merged in cell order. Each
// cell's region (the cell + halo, clipped to the data's reach) is loaded from the spill
// within the region budget, segmented (segment.hpp) and cut into buildings: the
// footprints the cell owns, or the clusters whose anchor it holds (the halo growing
// while one touches the region's edge); a region over the budget is processed as its
// four quarters. Also the unmatched building points (--unmatched).
#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <exception>
#include <mutex>

#ifdef __GLIBC__  // (defined by the C++ headers above)
#include <malloc.h>
#endif

#include "citylod/io/error.hpp"
#include "citylod/tiler/option_names.hpp"
#include "citylod/tiler/threads.hpp"
#include "split_internal.hpp"

namespace citylod::tiler::split_detail {

namespace {

/// A footprint id as a chunk id: a safe file name of at most 120 characters.
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

// Hands the heap's free memory back to the system between cells once it holds more than
// `keep` bytes: glibc keeps up to its trim threshold free, and that threshold grows with
// the largest block freed so far (the ingest's batches), so a cell's freed regions stayed
// resident through the next cells. Trimming after every cell cost a quarter of the
// pass's time on a scene of small buildings (the pages handed back, the TLBs of the
// other threads flushed, the pages faulted in again by the next region).
constexpr std::size_t kFreeKeptShare = 32;  ///< of --memory-limit: 64 MiB at the default 2G

void release_free_memory(std::size_t keep) {
#ifdef __GLIBC__
  if (mallinfo2().fordblks > keep) malloc_trim(0);
#else
  (void)keep;
#endif
}

}  // namespace

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

// A region over the budget at the smallest cell: one line with the cell, the budget and
// what helps.
void Splitter::region_too_large(const CellKey& key, double size, const std::string& what) const {
  throw IoError(opt_.work_dir,
                "cell " + std::to_string(key.first) + "," + std::to_string(key.second) + " (" +
                    fmt("%.2f", size) + " m" + what + ", halo " + fmt("%.0f", opt_.halo) +
                    " m) holds more than the " + std::to_string(region_budget_points_) +
                    " points (mesh scenes: samples + faces) " + option_name("memory_limit") + " " +
                    fmt("%.0f", double(opt_.memory_limit) / 1048576) +
                    "M allows, even at the smallest cell size: raise " +
                    option_name("memory_limit") + " (or lower " + option_name("halo") + ")");
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
                            ": a building larger than " + option_name("max_halo") + " was cut");
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
  // A point goes to a footprint whose box + buffer holds it: those beyond all the owned
  // ones' (the halo's) belong to none of them.
  std::array<double, 4> reach{INFINITY, INFINITY, -INFINITY, -INFINITY};
  for (std::size_t i : owned) {
    const auto& b = fps_[i].bbox;
    reach = {std::min(reach[0], b[0] - opt_.footprint_buffer),
             std::min(reach[1], b[1] - opt_.footprint_buffer),
             std::max(reach[2], b[2] + opt_.footprint_buffer),
             std::max(reach[3], b[3] + opt_.footprint_buffer)};
  }
  // At the spill's cell size the region holds all of the cell's points: their building
  // points outside every footprint are counted here (count_unmatched reads the others).
  const bool count_own = mode_ == ClassMode::buildings && c == spill.cell();
  std::int64_t unmatched = 0;
  for (std::size_t k = 0; !mesh_scene_ && k < pts.pos.size(); ++k) {
    const Vec3d& p = pts.pos[k];
    const bool own = count_own && pts.cls[k] == 6 && spill.key(p[0], p[1]) == key;
    if (!own && (p[0] < reach[0] || p[0] > reach[2] || p[1] < reach[1] || p[1] > reach[3]))
      continue;
    if (mode_ == ClassMode::buildings) {
      if (pts.cls[k] != 6) continue;
    } else {
      if (seg.ground[k] || seg.hag[k] < opt_.seg.ground_tolerance) continue;
      if (have_cls && non_building_class(pts.cls[k])) continue;
      if (seg.foliage[k] && seg.hag[k] >= opt_.seg.min_height) continue;
    }
    const std::size_t best = footprint_of({pts.pos[k][0], pts.pos[k][1]}, *job.fp);
    if (own && best == SIZE_MAX) ++unmatched;
    if (best != SIZE_MAX && mine.count(best))
      members[best].push_back(static_cast<std::uint32_t>(k));
  }
  if (count_own) out.unmatched.emplace_back(key, unmatched);
  for (std::size_t i : owned) {
    const auto it = members.find(i);
    const std::size_t count = it == members.end() ? 0 : it->second.size();
    if (count < static_cast<std::size_t>(std::max(1, opt_.min_footprint_points))) {
      CellOutput::Chunk& ch = out.chunks.emplace_back();
      ch.pc.rec.id = fp_chunk_id_[i];
      ch.named = true;
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
    CellOutput::Chunk& ch = emit_chunk(pts, seg, it->second, fp_chunk_id_[i],
                                       "footprint:" + fps_[i].id, fps_[i].main_ring(), out);
    ch.pc.rec.attributes = fps_[i].attributes;
    ch.pc.rec.id = fp_chunk_id_[i];
    ch.named = true;
    if (ch.write) write_chunk_file(ch);
  }
}

void Splitter::pass3_cells(const Spiller& spill) {
  std::vector<CellKey> cells;
  if (opt_.footprints.empty()) {
    for (const auto& [k, n] : spill.counts()) cells.push_back(k);
  } else {
    for (const auto& [k, v] : fp_owned_) cells.push_back(k);
  }
  rep_.cells = spill.counts().size();
  // Footprint chunks are named before the cells run (a name taken twice gets "-2", in
  // footprint order), so that the workers write their files.
  fp_chunk_id_.clear();
  for (const Footprint& f : fps_) fp_chunk_id_.push_back(unique_id("fp-" + sanitize_id(f.id)));
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
    rep_.notes.push_back(std::to_string(subdivided_) + " cells processed in quarters to fit " +
                         option_name("memory_limit"));
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
  const std::size_t free_kept = opt_.memory_limit / kFreeKeptShare;
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
      release_free_memory(free_kept);
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
  // The cells pass 3 did not count: each one's file on the split's threads (a footprint
  // cache per worker), summed in order.
  std::vector<CellKey> cells;
  std::int64_t out = 0;
  for (const auto& [k, n] : spill.counts()) {
    const auto counted = unmatched_by_cell_.find(k);
    if (counted == unmatched_by_cell_.end())
      cells.push_back(k);
    else
      out += counted->second;
  }
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
  for (const std::int64_t n : per_cell) out += n;
  rep_.building_points = std::int64_t(class_hist_[6]);
  rep_.unmatched_points = out;
  char b[256];
  std::snprintf(b, sizeof b,
                "%lld of %lld building (class 6) points lie outside every footprint (%.1f %%): ",
                static_cast<long long>(out), static_cast<long long>(class_hist_[6]),
                class_hist_[6] ? 100.0 * double(out) / double(class_hist_[6]) : 0.0);
  const std::string unmatched = option_name("unmatched");
  rep_.notes.push_back(
      b + (opt_.unmatched == SplitOptions::Unmatched::segment
               ? "clustered into buildings without footprint (" + unmatched + " segment)"
               : "dropped (" + unmatched + " drop)"));
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

}  // namespace citylod::tiler::split_detail
