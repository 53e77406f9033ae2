// The LOD stage (lod_stage.hpp): parameters of a city run, one building, and
// every building of a work directory.
#include "citylod/tiler/lod_stage.hpp"
#include "citylod/tiler/option_names.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <exception>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "citylod/io/atomic_file.hpp"
#include "citylod/io/error.hpp"
#include "citylod/io/hash.hpp"
#include "citylod/io/json_file.hpp"
#include "citylod/tiler/bridge.hpp"
#include "citylod/tiler/dir_lock.hpp"
#include "citylod/tiler/log.hpp"
#include "citylod/tiler/threads.hpp"

namespace citylod::tiler {

namespace fs = std::filesystem;

namespace {
constexpr const char* kEngineVersion = "citylod-lod-14";
}  // namespace

// ------------------------------------------------------------ parameters
lod::LodParams city_lod_params() {
  lod::LodParams p;
  p.closure.terrain = lod::Terrain::Cut;
  p.closure.footprint_walls = true;
  // Roof steps down to 0.5 m on a footprint (lod params.hpp, airborne.step_min).
  p.airborne.step_min = 0.5;
  return p;
}

void apply_lod_settings(lod::LodParams& p, const std::string& list) {
  std::stringstream ss(list);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item.empty()) continue;
    const auto eq = item.find('=');
    if (eq == std::string::npos)
      throw std::invalid_argument(option_name("set") + " expects NAME=VALUE, got '" + item + "'");
    try {
      p.set(item.substr(0, eq), item.substr(eq + 1));
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(option_name("set") + ": " + e.what());
    }
  }
}

void apply_lod_config(lod::LodParams& p, const std::string& path) {
  const nlohmann::json j = io::read_json_file(path);
  if (!j.is_object()) throw std::runtime_error(path + ": expected a JSON object of parameters");
  for (const auto& [k, v] : j.items()) {
    if (k == kThreadsKey) continue;  // a params.json records the threads it ran on
    try {
      p.set(k, v.is_string() ? v.get<std::string>() : v.dump());
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(path + ": " + e.what());
    }
  }
}

lod::LodParams params_for(const lod::LodParams& global, const Overrides& o, const std::string& id) {
  lod::LodParams p = global;
  auto it = o.find(id);
  if (it != o.end())
    for (const auto& [k, v] : it->second.set) p.set(k, v);
  return p;
}

std::string lod_key(const std::string& content_hash, const lod::LodParams& p) {
  std::string s = std::string(kEngineVersion) + "|" + content_hash;
  for (const auto& [k, v] : p.items()) s += "|" + k + "=" + v;
  return io::hash_hex(s.data(), s.size());
}

void parse_shard(const std::string& s, int& index, int& count) {
  const auto slash = s.find('/');
  try {
    if (slash == std::string::npos) throw std::invalid_argument("");
    size_t a = 0, b = 0;
    index = std::stoi(s.substr(0, slash), &a);
    count = std::stoi(s.substr(slash + 1), &b);
    if (a != slash || b != s.size() - slash - 1) throw std::invalid_argument("");
  } catch (const std::exception&) {
    throw std::invalid_argument(option_name("shard") + " expects I/N, got '" + s + "'");
  }
  if (count < 1 || index < 0 || index >= count)
    throw std::invalid_argument(option_name("shard") + " " + s + ": need 0 <= I < N");
}

// ------------------------------------------------------------ one building
BuildingLodResult build_building_lod(const BuildingLodOptions& o, const ProgressFn& progress) {
  BuildingLodResult out;
  out.building = load_building(o.input);
  const LoadedBuilding& b = out.building;
  log_info("lod: " + o.input + ": " + std::to_string(b.input.points.size()) +
           (b.is_mesh ? " vertices, " + std::to_string(b.input.triangles.size()) + " triangles"
                      : std::string(" points") +
                            (b.input.normals.empty() ? " (no normals)" : " with normals")));
  struct Ctx {
    const ProgressFn* fn;
  } ctx{&progress};
  lod::LodExecution exec;
  exec.threads = o.threads;
  exec.user = &ctx;
  if (progress)
    exec.progress = [](double f, const char* stage, void* user) {
      const ProgressFn& fn = *static_cast<Ctx*>(user)->fn;
      ProgressEvent e;
      e.task = "lod";
      e.fraction = f;
      e.detail = stage;
      return fn(e);
    };
  try {
    out.result = lod::build_lod_tree(b.input, o.params, exec);
  } catch (const lod::LodError& e) {
    throw std::runtime_error(o.input + ": " + e.what());
  }
  notify_finished(progress, "lod");
  out.files = write_lod_output(o.out_dir, out.result, o.params, exec.threads, o.input, b.origin,
                               o.dump_planes);
  return out;
}

// ------------------------------------------------------------ a work directory
namespace {

/// The key recorded in a finished building's report.json ("" when absent/unreadable).
std::string recorded_key(const std::string& work, const std::string& id) {
  try {
    const auto r = find_lod_report(work, id);
    return r ? r->key : "";
  } catch (const std::exception&) {
    return "";
  }
}

/// f(0..n-1) on `threads` std::threads (run_workers), dynamic schedule; the first
/// exception is rethrown after all have joined. Not OpenMP: the stage runs in a forked
/// child (supervise.hpp).
void run_parallel(std::size_t n, int threads, const std::function<void(std::size_t)>& f) {
  std::atomic<std::size_t> next{0};
  std::exception_ptr error;
  std::mutex error_mutex;
  auto worker = [&]() {
    for (std::size_t i; (i = next++) < n;) {
      try {
        f(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
      }
    }
  };
  run_workers(std::max(1, threads), n, worker);
  if (error) std::rethrow_exception(error);
}

/// A building's ".running" marker: a plain file, neither synced nor renamed
/// into place. It matters only to the supervisor after a crash of this
/// process, whose writes the page cache keeps; a run cut by a power loss
/// leaves markers that the next run removes (remove_stale_stages).
void write_marker(const std::string& path, const std::string& id) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f << id << '\n';
  f.close();
  if (!f) throw io::IoError(path, "cannot write the building's marker");
}

struct Outcome {
  Status status = Status::failed;
  std::string reason;
};

/// Publishes the buildings' staged directories on a thread of its own, in
/// batches (io::publish_directories: one syncfs for all that are waiting), so
/// that the workers do not wait for the disk (a building's syncfs and fsyncs
/// took ~2 ms, 15 % of the LOD stage of median City3D buildings on 2
/// threads). A building killed before its publication is computed again by
/// the next run, as one killed before its rename was. In practice the thread
/// keeps pace (796 syncfs for 800 median City3D buildings): the gain is that
/// the workers do not wait. finish() waits for all and rethrows the first
/// failure.
class Publisher {
 public:
  Publisher() : thread_([this] { loop(); }) {}
  ~Publisher() {  // an exception left the stage: what is queued is still published
    stop();
    if (thread_.joinable()) thread_.join();
  }
  Publisher(const Publisher&) = delete;
  Publisher& operator=(const Publisher&) = delete;

  /// Publishes `stage` as `dir`, then removes `then_remove` (when not empty):
  /// a marker that must outlive the building's unpublished output.
  void publish(std::string stage, std::string dir, std::string then_remove) {
    std::lock_guard<std::mutex> lock(mu_);
    queue_.push_back({std::move(stage), std::move(dir)});
    remove_.push_back(std::move(then_remove));
    cv_.notify_one();
  }
  void finish() {
    stop();
    thread_.join();
    if (error_) std::rethrow_exception(error_);
  }

 private:
  void stop() {
    std::lock_guard<std::mutex> lock(mu_);
    done_ = true;
    cv_.notify_one();
  }
  void loop() {
    std::unique_lock<std::mutex> lock(mu_);
    for (;;) {
      cv_.wait(lock, [this] { return done_ || !queue_.empty(); });
      if (queue_.empty()) return;  // done
      std::vector<std::pair<std::string, std::string>> batch;
      std::vector<std::string> remove;
      batch.swap(queue_);
      remove.swap(remove_);
      lock.unlock();
      try {
        io::publish_directories(batch);
        for (const auto& p : remove)
          if (!p.empty()) fs::remove(p);
      } catch (...) {
        lock.lock();
        if (!error_) error_ = std::current_exception();
        continue;
      }
      lock.lock();
    }
  }

  std::mutex mu_;
  std::condition_variable cv_;
  std::vector<std::pair<std::string, std::string>> queue_;
  std::vector<std::string> remove_;  ///< per queued pair
  bool done_ = false;
  std::exception_ptr error_;
  std::thread thread_;  ///< last: started once the members above exist
};

/// Runs one building and has WORK/lod/<id>/ published atomically by
/// `publisher` (its report.json carries the resume key). Never throws for the building's own
/// trouble: the reason goes into the report. A building that crashed an earlier run is not retried:
/// it gets the engine's fallback model.
Outcome process_building(const std::string& work, const ChunkRecord& c, const lod::LodParams& p,
                         const std::string& key, bool crashed_before, Publisher& publisher) {
  const std::string dir = lod_dir(work, c.id);
  const std::string stage = io::staging_path(dir);
  fs::remove_all(stage);
  lod::LodResult r;
  try {
    if (!crashed_before && !chunk_intact(work, c))
      throw std::runtime_error(chunk_path(work, c.id) +
                               ": missing, truncated or changed since split (its hash is not the "
                               "manifest's); run '" +
                               rerun_name("split", "force") + "' again");
    const lod::BuildingInput in = chunk_input(work, c);
    r = crashed_before ? lod::fallback_result(in, "crashed in an earlier run; not retried")
                       : lod::build_lod_tree(in, p);
  } catch (const std::exception& e) {  // unreadable chunk, or no model at all (no points, no area)
    r = lod::LodResult{};
    r.status = Status::failed;
    r.reason = e.what();
  }
  {
    const io::StagedDirectory staged(stage);  // its files written in place, synced once below
    write_lod_output(stage, r, p, 1, chunk_path(work, c.id), {0, 0, 0}, false, c.id, key);
  }
  // a crashed building's marker goes once its fallback is published
  publisher.publish(stage, dir,
                    crashed_before ? lod_marker_path(work, c.id, LodMarker::crashed) : "");
  return {r.status, r.reason};
}

/// Removes what a run killed from outside (SIGKILL, a node's time limit) left in
/// WORK/lod for these buildings: "<id>.tmp.<pid>" (a building's output before
/// its rename), "<id>.running.tmp.<pid>" and "<id>.running" (its marker). A
/// crash inside a supervised run turned the markers into .crashed/.suspect
/// already; these are what nobody was left to clean. Only this plan's buildings:
/// a shard running beside this one owns the others. Called under the stage's
/// lock, so no live run of these buildings writes them.
void remove_stale_stages(const std::string& work, const LodStagePlan& plan) {
  std::set<std::string> ids;
  for (const auto& it : plan.items) ids.insert(it.chunk->id);
  std::error_code ec;
  std::vector<fs::path> stale;
  for (fs::directory_iterator e(lod_root(work), ec), end; !ec && e != end; e.increment(ec)) {
    const std::string name = e->path().filename().string();
    const std::string staged = io::staged_for(name);  // "<id>" or "<id>.running", or ""
    const std::string base = staged.empty() ? name : staged;
    std::string id = marker_id(base, LodMarker::running);
    if (id.empty()) id = staged;
    if (id.empty()) continue;  // neither staged nor a marker
    if (ids.count(id)) stale.push_back(e->path());
  }
  for (const auto& p : stale) fs::remove_all(p, ec);
}

}  // namespace

std::size_t LodStagePlan::up_to_date() const {
  return std::size_t(
      std::count_if(items.begin(), items.end(), [](const Item& i) { return i.up_to_date; }));
}

namespace {
bool sharded(const LodStageOptions& o) {
  return o.shard_count > 1 && o.only.empty();
}
}  // namespace

LodStageLock::LodStageLock(const LodStageOptions& o)
    : work_(o.work_dir, sharded(o) ? DirLock::Mode::shared : DirLock::Mode::exclusive) {
  if (sharded(o)) shard_.emplace(DirLock::for_shard(o.work_dir, o.shard_index, o.shard_count));
}

LodStagePlan plan_lod_stage(const LodStageOptions& o) {
  LodStagePlan plan;
  plan.manifest = read_manifest(o.work_dir);
  const lod::LodParams& params = o.params;  // one thread per building: parallel across them
  params.validate();
  const Overrides overrides = read_overrides(o.work_dir);
  // This shard's chunks (rank in id order, so every shard agrees), largest first.
  std::vector<const ChunkRecord*> todo;
  const auto& chunks = plan.manifest.chunks;
  for (size_t i = 0; i < chunks.size(); ++i) {
    const auto& c = chunks[i];
    if (!o.only.empty() && std::find(o.only.begin(), o.only.end(), c.id) == o.only.end()) continue;
    if (o.only.empty() && int(i % size_t(o.shard_count)) != o.shard_index) continue;
    if (c.skipped()) continue;
    todo.push_back(&c);
  }
  std::stable_sort(todo.begin(), todo.end(), [](const ChunkRecord* a, const ChunkRecord* b) {
    const auto sa = a->points + a->triangles, sb = b->points + b->triangles;
    return sa != sb ? sa > sb : a->id < b->id;
  });
  for (const ChunkRecord* c : todo) {
    LodStagePlan::Item it;
    it.chunk = c;
    it.params = params_for(params, overrides, c->id);
    it.key = lod_key(c->content_hash, it.params);
    it.up_to_date = o.only.empty() && recorded_key(o.work_dir, c->id) == it.key;
    plan.items.push_back(std::move(it));
  }
  return plan;
}

LodStageReport run_lod_stage(const LodStageOptions& o, const ProgressFn& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  LodStageReport rep;
  const LodStagePlan plan = plan_lod_stage(o);
  const LodStageLock lock(o);  // one writer (dir_lock.hpp); held already in a city run
  rep.total = plan.items.size();
  fs::create_directories(lod_root(o.work_dir));
  remove_stale_stages(o.work_dir, plan);

  std::mutex mu;
  size_t done = 0;
  Publisher publisher;
  auto run_one = [&](const LodStagePlan::Item& item) {
    const ChunkRecord& c = *item.chunk;
    const std::string running = lod_marker_path(o.work_dir, c.id, LodMarker::running),
                      suspect = lod_marker_path(o.work_dir, c.id, LodMarker::suspect),
                      crashed = lod_marker_path(o.work_dir, c.id, LodMarker::crashed);
    Outcome out;
    bool reused = false;
    if (item.up_to_date) {
      reused = true;
      try {
        const auto r = find_lod_report(o.work_dir, c.id);
        if (r) out = {r->status, r->reason};
      } catch (const std::exception& e) {
        out = {Status::failed, e.what()};
      }
    } else {
      const bool crashed_before = fs::exists(crashed);
      write_marker(running, c.id);
      fs::remove(suspect);
      out = process_building(o.work_dir, c, item.params, item.key, crashed_before, publisher);
      fs::remove(running);
    }
    std::lock_guard<std::mutex> lock(mu);
    (reused ? rep.reused : rep.computed)++;
    rep.add_lod_outcome(out.status);
    if (out.status != Status::ok) rep.problems.emplace_back(c.id, out.reason);
    ++done;
    notify_count(progress, "lod", done, rep.total, "buildings");
  };
  // Buildings that were running when an earlier process crashed go first, one
  // at a time: if one crashes again it is the only one running, and the
  // supervisor (supervise.hpp) marks it crashed.
  std::vector<const LodStagePlan::Item*> rest;
  for (const auto& it : plan.items) {
    if (fs::exists(lod_marker_path(o.work_dir, it.chunk->id, LodMarker::suspect)))
      run_one(it);
    else
      rest.push_back(&it);
  }
  run_parallel(rest.size(), std::max(1, o.threads), [&](std::size_t i) { run_one(*rest[i]); });
  publisher.finish();
  notify_finished(progress, "lod");
  std::sort(rep.problems.begin(), rep.problems.end());
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return rep;
}

}  // namespace citylod::tiler
