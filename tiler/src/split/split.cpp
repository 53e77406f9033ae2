// `citylod split`: georeferenced, out-of-core ingest and building splitting.
// See split.hpp for the passes and split_internal.hpp for the files that run them;
// this one runs them in order: the up-to-date check, passes 1-3, the manifest.
#include "citylod/tiler/split.hpp"

#include <chrono>
#include <filesystem>

#include "citylod/io/error.hpp"
#include "citylod/tiler/log.hpp"
#include "split_internal.hpp"

namespace citylod::tiler {

namespace split_detail {

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

  // Each pass's wall time, for --log-level debug (where a split's time goes).
  auto mark = t0;
  const auto lap = [&mark](const char* what) {
    const auto now = std::chrono::steady_clock::now();
    log_debug(std::string("split: ") + what + " " +
              fmt("%.2f s", std::chrono::duration<double>(now - mark).count()));
    mark = now;
  };
  if (!opt_.footprints.empty()) read_footprints();
  lap("footprints read");
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
  lap("headers, georeference, cells");
  pass2_spill(spill);
  lap("pass 2 (read, spill)");
  if (!opt_.footprints.empty()) load_footprints();
  lap("footprints placed");
  pass3_cells(spill);
  lap("pass 3 (regions, chunks)");
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
  lap("manifest, commit");
  stages_.report(0.97, 1.0, 1.0, "done");
  rep_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return rep_;
}

}  // namespace split_detail

SplitReport split_scene(const SplitOptions& options, const ProgressFn& progress) {
  split_detail::Splitter s(options, progress);
  SplitReport r = s.run();
  notify_finished(progress, "split");
  return r;
}

}  // namespace citylod::tiler
