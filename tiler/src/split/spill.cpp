// The split's spill storage: the point spiller's writer and the work directory
// transaction (see spill.hpp).
#include "spill.hpp"

#include <unistd.h>
#include <csignal>

#include <cstdlib>

namespace citylod::tiler::split_detail {

/// `buf` out by cell, each cell's records in arrival order: the cell of each record
/// computed once, a counting sort of the records by cell (a scene's buffer meets few
/// cells), each cell's run written through a piece buffer. (A comparison sort
/// recomputing both keys per comparison took 20 % of a split.)
void Spiller::write(const std::vector<SpillRec>& buf) {
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

Staging::Staging(const fs::path& work) : work_(work) {
  created_work_ = !fs::exists(work_);
  std::error_code ec;
  fs::create_directories(work_, ec);
  if (ec) throw IoError(work_.string(), "cannot create work directory: " + ec.message());
  remove_stale();
  dir_ = split_staging_dir(work_.string(), long(::getpid()));
  fs::remove_all(dir_, ec);
  fs::create_directories(spill(), ec);
  fs::create_directories(chunks(), ec);
  fs::create_directories(faces(), ec);
  if (ec) throw IoError(dir_.string(), "cannot create staging directory: " + ec.message());
  // Chunks written in place (no temp file, fsync or rename each), made durable by one
  // syncfs in commit(): a chunk's fsync was 7 % of a replica's split and most of its wait.
  staged_ = std::make_unique<io::StagedDirectory>(dir_.string());
}

Staging::~Staging() {
  std::error_code ec;
  fs::remove_all(dir_, ec);
  if (!committed_ && created_work_ && fs::is_empty(work_, ec)) fs::remove(work_, ec);
}

void Staging::commit(const Manifest& m) {
  const fs::path live = chunks_dir(work_.string());
  const fs::path old = split_old_chunks_dir(dir_.string());
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

void Staging::remove_stale() {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(work_, ec)) {
    const long pid = split_staging_pid(e.path().filename().string());
    if (pid < 0) continue;  // not a staging folder
    if (pid > 0 && pid != ::getpid() && ::kill(static_cast<pid_t>(pid), 0) == 0)
      throw IoError(work_.string(), "another 'citylod split' (pid " + std::to_string(pid) +
                                        ") is writing this work directory");
    std::error_code e2;
    fs::remove_all(e.path(), e2);
  }
}

}  // namespace citylod::tiler::split_detail
