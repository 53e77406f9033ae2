// The split's chunks: a building's chunk made from its region (emit_chunk: its record,
// its points in chunk coordinates, or its claims on mesh triangles), a cell's chunks
// merged into the split in cell order (merge_cell: named, written), and the mesh
// chunks written at the end from the resolved claims (write_mesh_chunks).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numeric>
#include <unordered_map>

#include "citylod/io/atomic_file.hpp"
#include "citylod/io/hash.hpp"
#include "citylod/io/writers.hpp"
#include "split_internal.hpp"

namespace citylod::tiler::split_detail {

namespace {

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  const auto mid = v.begin() + static_cast<long>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace

// Points on the inputs' grid as one integer each, ordered as their coordinates are
// (x, then y, then z: a step count is monotonic in the coordinate it rounds to): the
// steps from the chunk's smallest, 21 bits an axis. nullopt without a grid on every
// axis or when a chunk spans more steps.
std::optional<std::vector<std::uint64_t>> Splitter::grid_keys(
    const std::vector<Vec3d>& local) const {
  if (local.empty() || grid_[0] <= 0 || grid_[1] <= 0 || grid_[2] <= 0) return std::nullopt;
  constexpr int kBits = 21;
  std::vector<std::array<std::int64_t, 3>> steps(local.size());
  std::array<std::int64_t, 3> lo{INT64_MAX, INT64_MAX, INT64_MAX};
  std::array<std::int64_t, 3> hi{INT64_MIN, INT64_MIN, INT64_MIN};
  for (std::size_t i = 0; i < local.size(); ++i)
    for (std::size_t a = 0; a < 3; ++a) {
      const double n = std::round(local[i][a] / grid_[a]);
      if (!(std::abs(n) < 1e15)) return std::nullopt;
      steps[i][a] = std::int64_t(n);
      lo[a] = std::min(lo[a], steps[i][a]);
      hi[a] = std::max(hi[a], steps[i][a]);
    }
  for (std::size_t a = 0; a < 3; ++a)
    if (hi[a] - lo[a] >= (std::int64_t(1) << kBits)) return std::nullopt;
  std::vector<std::uint64_t> keys(local.size());
  for (std::size_t i = 0; i < local.size(); ++i)
    keys[i] = std::uint64_t(steps[i][0] - lo[0]) << (2 * kBits) |
              std::uint64_t(steps[i][1] - lo[1]) << kBits | std::uint64_t(steps[i][2] - lo[2]);
  return keys;
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
  const auto ties = [&](std::uint32_t a, std::uint32_t b) {  // same position
    const std::uint32_t ka = members[a], kb = members[b];
    if (has_classes_ && pts.cls[ka] != pts.cls[kb]) return pts.cls[ka] < pts.cls[kb];
    if (has_colors_ && pts.rgb[ka] != pts.rgb[kb]) return pts.rgb[ka] < pts.rgb[kb];
    if (has_normals_ && pts.nrm[ka] != pts.nrm[kb]) return pts.nrm[ka] < pts.nrm[kb];
    return false;
  };
  std::vector<std::uint32_t> order(members.size());
  std::iota(order.begin(), order.end(), 0u);
  if (const auto keys = grid_keys(local)) {
    // the same order through one integer per point (the grid steps of x, y, z packed)
    std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
      if ((*keys)[a] != (*keys)[b]) return (*keys)[a] < (*keys)[b];
      return ties(a, b);
    });
  } else {
    std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
      if (local[a] != local[b]) return local[a] < local[b];
      return ties(a, b);
    });
  }
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

// A chunk's points to WORK/chunks/<id>.ply (its id final), hashed as written; on the
// pass-3 workers for footprint chunks, named before the cells run.
void Splitter::write_chunk_file(CellOutput::Chunk& ch) const {
  ChunkRecord& rec = ch.pc.rec;
  const std::string path = (staging_->chunks() / (rec.id + ".ply")).string();
  io::PlyWriteOptions wo;
  wo.comment = "citylod chunk " + rec.id + " (xyz relative to the chunk origin, scene " +
               std::string(georef_->scene_frame() == geo::SceneFrame::projected ? "CRS" : "ENU") +
               " metres)";
  const std::string bytes = io::ply_bytes(path, ch.points, wo);
  io::atomic_write_file(path, bytes);
  rec.content_hash = io::hash_hex(bytes.data(), bytes.size());
  ch.points = io::PointSet{};
  ch.written = true;
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
    if (!ch.named) rec.id = unique_id(ch.base_id);
    if (ch.write) {
      if (!ch.written) write_chunk_file(ch);
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
  for (const auto& [k, n] : out.unmatched) unmatched_by_cell_[k] += n;
  subdivided_ += out.subdivided;
  fp_few_ += out.fp_few;
  fp_few_points_ += out.fp_few_points;
  fp_few_max_ = std::max(fp_few_max_, out.fp_few_max);
  out = CellOutput{};
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

}  // namespace citylod::tiler::split_detail
