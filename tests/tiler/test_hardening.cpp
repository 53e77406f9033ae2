// The library's defences of issue 13: work-directory records as untrusted
// input, one writer per directory, atomic publication.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "citylod/io/atomic_file.hpp"
#include "citylod/io/error.hpp"
#include "citylod/tiler/assemble.hpp"
#include "citylod/tiler/city_run.hpp"
#include "citylod/tiler/dir_lock.hpp"
#include "citylod/tiler/lod_stage.hpp"
#include "citylod/tiler/workdir.hpp"
#include "support/cli_run.hpp"
#include "tiler/test_work_support.hpp"

namespace fs = std::filesystem;
using namespace citylod;
using namespace citylod::tiler;

namespace {

fs::path fresh_dir(const std::string& name) {
  return test::tmp_dir("hardening_lib_" + name);
}

TEST(SafeIds, OnlyPlainFileNamesAreIds) {
  for (const std::string& ok :
       std::vector<std::string>{"fp-1", "b-0123abcdef01", "fp-NL.IMBAG.Pand.0503100000019480",
                                "fp-a_b-2", std::string(kMaxIdLength, 'x')})
    EXPECT_TRUE(is_safe_id(ok)) << ok;
  for (const std::string& bad : std::vector<std::string>{
           "", ".", "..", "../..", "a/b", "a\\b", ".hidden", "x..y", "a b",
           std::string(kMaxIdLength + 1, 'x'), std::string("a\0b", 3), "fp-\xc3\xa9"})
    EXPECT_FALSE(is_safe_id(bad)) << bad;
  EXPECT_THROW(lod_dir("w", "../.."), std::invalid_argument);
  EXPECT_THROW(chunk_path("w", "a/b"), std::invalid_argument);
  EXPECT_THROW(lod_report_path("w", ""), std::invalid_argument);
}

TEST(SafeIds, EveryRecordRefusesAnUnsafeId) {
  const fs::path d = fresh_dir("records");
  Manifest m;
  m.scene.origin_lon = 4;
  m.scene.origin_lat = 52;
  ChunkRecord c;
  c.id = "../..";
  m.chunks.push_back(c);
  write_manifest(d.string(), m);
  try {
    read_manifest(d.string());
    ADD_FAILURE() << "no error";
  } catch (const io::IoError& e) {
    EXPECT_EQ(e.file(), manifest_path(d.string()));
    EXPECT_NE(std::string(e.what()).find("'../..'"), std::string::npos) << e.what();
  }
  std::ofstream(overrides_path(d.string()))
      << R"({"buildings": {"../x": {"set": {"planes.epsilon": "0.2"}}}})";
  EXPECT_THROW(read_overrides(d.string()), std::runtime_error);
  const fs::path rep = d / "report.json";
  std::ofstream(rep) << R"({"status": "ok", "id": "a/b", "models": []})";
  EXPECT_THROW(read_lod_report(rep.string()), io::IoError);
  std::ofstream(rep, std::ios::trunc)
      << R"({"status": "ok", "models": [{"file": "../../etc/passwd"}]})";
  EXPECT_THROW(read_lod_report(rep.string()), io::IoError);
  std::ofstream(rep, std::ios::trunc) << R"({"status": "ok", "models": [{"file": "/etc/passwd"}]})";
  EXPECT_THROW(read_lod_report(rep.string()), io::IoError);
  std::ofstream(run_report_path(d.string())) << R"({"buildings": [{"id": ".."}]})";
  EXPECT_THROW(read_run_report(d.string()), std::runtime_error);
}

TEST(SafeIds, AWorkDirectoryWhoseFoldersAreLinksIsRefused) {
  const fs::path d = fresh_dir("links");
  const fs::path work = d / "work";
  Manifest m;
  write_manifest(work.string(), m);
  fs::create_directories(d / "elsewhere");
  fs::create_directory_symlink(d / "elsewhere", work / "chunks");
  EXPECT_THROW(read_manifest(work.string()), io::IoError);
}

// ------------------------------------------------------------ one writer per directory

/// A child process holding DirLock(dir) until the returned pipe is closed.
struct LockHolder {
  pid_t pid = -1;
  int release = -1;
  /// shard < 0: DirLock(dir); else the LOD stage lock of shard `shard` of 2.
  explicit LockHolder(const std::string& dir, int shard = -1) {
    int ready[2], go[2];
    EXPECT_EQ(::pipe(ready), 0);
    EXPECT_EQ(::pipe(go), 0);
    pid = ::fork();
    if (pid == 0) {
      ::close(ready[0]);
      ::close(go[1]);
      {
        LodStageOptions o;
        o.work_dir = dir;
        o.shard_index = shard;
        o.shard_count = 2;
        std::optional<DirLock> whole;
        std::optional<LodStageLock> stage;
        if (shard < 0)
          whole.emplace(dir);
        else
          stage.emplace(o);
        char c = 1;
        if (::write(ready[1], &c, 1) != 1) ::_exit(2);
        ::read(go[0], &c, 1);  // until the parent closes its end
      }
      ::_exit(0);
    }
    ::close(ready[1]);
    ::close(go[0]);
    char c = 0;
    EXPECT_EQ(::read(ready[0], &c, 1), 1);
    ::close(ready[0]);
    release = go[1];
  }
  ~LockHolder() {
    ::close(release);
    int st = 0;
    ::waitpid(pid, &st, 0);
  }
};

TEST(DirLock, ASecondWriterRefusesAtOnceNamingTheDirectoryAndTheHolder) {
  const fs::path d = fresh_dir("lock");
  {
    LockHolder holder(d.string());
    try {
      DirLock again(d.string());
      ADD_FAILURE() << "locked twice";
    } catch (const DirBusy& e) {
      EXPECT_EQ(e.pid(), long(holder.pid));
      EXPECT_NE(std::string(e.what()).find(d.string()), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("pid " + std::to_string(holder.pid)), std::string::npos)
          << e.what();
    }
    // every writer of that directory refuses: tile, lod WORK, assemble, rebuild
    CityRunOptions o;
    o.out_dir = d.string();
    o.split.inputs = {"no-such-input.las"};
    EXPECT_THROW(run_city(o), DirBusy);
    LodStageOptions lo;
    lo.work_dir = d.string();
    write_manifest(d.string(), test::synthetic_manifest());
    EXPECT_THROW(run_lod_stage(lo), DirBusy);
    EXPECT_THROW(assemble(d.string(), (d / "ts").string(), AssembleParams{}), DirBusy);
  }
  // released when the holder ends; nested locks of one process are counted
  DirLock a(d.string());
  { DirLock b(d.string()); }
  EXPECT_TRUE(fs::exists(d / ".citylod.lock"));
}

TEST(DirLock, TheShardsOfOneLodStageRunAtOnceAndExcludeEveryOtherWriter) {
  const fs::path d = fresh_dir("lock_shards");
  LockHolder shard0(d.string(), 0);
  LodStageOptions o;
  o.work_dir = d.string();
  o.shard_count = 2;
  o.shard_index = 1;
  { LodStageLock other_shard(o); }  // shard 1 runs beside shard 0
  o.shard_index = 0;
  EXPECT_THROW(LodStageLock same_shard(o), DirBusy);
  EXPECT_THROW(DirLock whole(d.string()), DirBusy);  // tile, split, assemble, lod WORK
  o.shard_count = 1;
  EXPECT_THROW(LodStageLock unsharded(o), DirBusy);
}

TEST(DirLock, AFinishedRunLeavesNoLockFileAndNoDirectoryItCreated) {
  const fs::path d = fresh_dir("lock_clean") / "new";
  { DirLock l(d.string()); }
  EXPECT_FALSE(fs::exists(d));
}

// ------------------------------------------------------------ atomic publication

/// Runs f in a child whose publication hook ends the process at step `k`.
/// Returns true when f finished before step k (no kill).
bool run_killed_at(int k, const std::function<void()>& f) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    int n = 0;
    io::set_publication_hook([&](const std::string&) {
      if (n++ == k) ::_exit(77);
    });
    try {
      f();
    } catch (...) {
      ::_exit(3);
    }
    ::_exit(0);
  }
  int st = 0;
  ::waitpid(pid, &st, 0);
  EXPECT_TRUE(WIFEXITED(st));
  EXPECT_NE(WEXITSTATUS(st), 3) << "the run failed at step " << k;
  return WEXITSTATUS(st) == 0;
}

void copy_tree(const fs::path& from, const fs::path& to) {
  fs::remove_all(to);
  fs::copy(from, to, fs::copy_options::recursive);
}

TEST(Publication, AssembleKilledAtAnyStepLeavesThePreviousOrTheNewTileset) {
  const fs::path d = fresh_dir("publish");
  const std::string work = (d / "work").string(), out = (d / "out").string();
  AssembleParams p;
  p.threads = 1;
  p.building_models = true;  // more files in the stage: more steps to be killed at
  test::write_work(work, test::synthetic_manifest(), test::synthetic_city(6, 3));
  assemble(work, out, p);
  const auto before = test::dir_contents(out);
  copy_tree(out, d / "backup");
  test::write_work((d / "work2").string(), test::synthetic_manifest(),
                   test::synthetic_city(9, 3, 25.0));
  assemble((d / "work2").string(), (d / "expected").string(), p);
  const auto after = test::dir_contents((d / "expected").string());
  ASSERT_NE(before, after);
  fs::remove_all(work);
  fs::rename(d / "work2", work);
  int kills = 0;
  for (int k = 0;; ++k) {
    copy_tree(d / "backup", out);
    const bool finished = run_killed_at(k, [&] { assemble(work, out, p); });
    const auto now = test::dir_contents(out);
    EXPECT_TRUE(now == before || now == after) << "killed at step " << k;
    if (finished) {
      EXPECT_EQ(now, after);
      break;
    }
    ++kills;
    ASSERT_LT(k, 10000);
  }
  EXPECT_GE(kills, 12);  // every file of the stage, the switch, the clean-up
  // a run after a kill finishes the job
  copy_tree(d / "backup", out);
  run_killed_at(kills - 1, [&] { assemble(work, out, p); });
  assemble(work, out, p);
  EXPECT_EQ(test::dir_contents(out), after);
  EXPECT_FALSE(fs::exists(out + ".partial"));
}

}  // namespace
