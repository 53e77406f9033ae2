// examples/slurm on a real single-node Slurm cluster started on localhost from
// the Debian packages (slurm-wlm, munge): split job -> lod array job (--shard) ->
// assemble job (afterok); the tileset must equal a local `citylod tile` run
// byte for byte. Skips only when slurmctld cannot be started.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>
#include "support/cli_run.hpp"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>

namespace fs = std::filesystem;

namespace {

using namespace citylod::test;

pid_t read_pid(const fs::path& f) {
  std::ifstream in(f);
  long p = 0;
  in >> p;
  return pid_t(p);
}

void stop(pid_t pid) {
  if (pid <= 1) return;
  kill(pid, SIGTERM);
  for (int i = 0; i < 100 && kill(pid, 0) == 0; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  if (kill(pid, 0) == 0) kill(pid, SIGKILL);
}

/// A single-node cluster in a temp dir; daemons stopped by pid in the destructor.
struct Cluster {
  fs::path dir, conf;
  pid_t ctld = 0, slurmd = 0, munged = 0;
  std::string why_not;  // set when slurmctld could not start

  explicit Cluster(const fs::path& d) : dir(d) {
    if (sh("command -v slurmctld && command -v slurmd && command -v sbatch && command -v munged")
            .code != 0) {
      why_not = "slurm-wlm / munge are not installed (scripts/install-deps.sh --with-test-tools)";
      return;
    }
    // munge: a key, and munged running as the munge user.
    if (sh("munge -n | unmunge").code != 0) {
      sh("mkdir -p /etc/munge /run/munge /var/log/munge /var/lib/munge && "
         "( [ -s /etc/munge/munge.key ] || dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 "
         "count=1 ) && "
         "chown -R munge:munge /etc/munge /run/munge /var/log/munge /var/lib/munge && chmod 400 "
         "/etc/munge/munge.key");
      const CliRun m =
          sh("runuser -u munge -- /usr/sbin/munged && sleep 0.5 && cat /run/munge/munged.pid");
      munged = pid_t(std::atol(m.out.c_str()));
      if (sh("munge -n | unmunge").code != 0) {
        why_not = "munged does not work: " + m.out;
        return;
      }
    }
    const std::string host = sh("hostname -s").out.substr(0, sh("hostname -s").out.find('\n'));
    const int cpus = int(sysconf(_SC_NPROCESSORS_ONLN));
    const int port = 20000 + int(getpid() % 20000);
    for (const char* s : {"state", "spool"}) fs::create_directories(dir / s);
    conf = dir / "slurm.conf";
    std::ofstream f(conf);
    f << "ClusterName=citylodtest\nSlurmctldHost=" << host << "\nSlurmUser=root\nSlurmdUser=root\n"
      << "SlurmctldPort=" << port << "\nSlurmdPort=" << port + 1 << "\nAuthType=auth/munge\n"
      << "StateSaveLocation=" << (dir / "state").string()
      << "\nSlurmdSpoolDir=" << (dir / "spool").string() << "\n"
      << "SlurmctldPidFile=" << (dir / "slurmctld.pid").string()
      << "\nSlurmdPidFile=" << (dir / "slurmd.pid").string()
      << "\nSlurmctldLogFile=" << (dir / "slurmctld.log").string()
      << "\nSlurmdLogFile=" << (dir / "slurmd.log").string()
      << "\nProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\nSelectType=select/cons_tres\n"
      << "SelectTypeParameters=CR_CPU\nJobAcctGatherType=jobacct_gather/"
         "none\nAccountingStorageType=accounting_storage/none\n"
      << "MailProg=/bin/true\nMpiDefault=none\nReturnToService=2\nSchedulerType=sched/backfill\n"
      << "NodeName=" << host << " CPUs=" << cpus << " State=UNKNOWN\n"
      << "PartitionName=debug Nodes=" << host << " Default=YES MaxTime=INFINITE State=UP\n";
    f.close();
    setenv("SLURM_CONF", conf.c_str(), 1);
    const CliRun c = sh("slurmctld -f " + q(conf));
    for (int i = 0; i < 50 && !fs::exists(dir / "slurmctld.pid"); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    ctld = read_pid(dir / "slurmctld.pid");
    bool up = false;
    for (int i = 0; i < 100 && c.code == 0 && ctld > 0 && !up; ++i) {
      up = sh("scontrol ping").out.find("is UP") != std::string::npos;
      if (!up) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    if (!up) {
      why_not = "slurmctld could not start: " + c.out + " " +
                slurp(dir / "slurmctld.log").substr(0, 2000);
      return;
    }
    sh("slurmd -f " + q(conf));
    for (int i = 0; i < 50 && !fs::exists(dir / "slurmd.pid"); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    slurmd = read_pid(dir / "slurmd.pid");
  }
  bool node_idle() {
    for (int i = 0; i < 300; ++i) {
      if (sh("sinfo -h -o %t").out.find("idle") != std::string::npos) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return false;
  }
  ~Cluster() {
    stop(slurmd);
    stop(ctld);
    stop(munged);
    unsetenv("SLURM_CONF");
  }
};

TEST(Slurm, ArrayJobTilesetEqualsLocalTileRun) {
  const fs::path d = fs::path(CITYLOD_TEST_TMP) / "slurm_cli";
  fs::remove_all(d);
  fs::create_directories(d);
  Cluster cluster(d / "cluster");
  if (!cluster.why_not.empty()) GTEST_SKIP() << cluster.why_not;
  ASSERT_TRUE(cluster.node_idle()) << sh("sinfo").out << slurp(d / "cluster" / "slurmd.log");

  const fs::path ex = fs::path(CITYLOD_SOURCE_DIR) / "examples";
  const std::string input = q(ex / "delft_small" / "delft_small.las") +
                            " --crs EPSG:28992 --footprints " +
                            q(ex / "delft_small" / "footprints.geojson");
  const CliRun local = sh(std::string(CITYLOD_BINARY) + " -q tile " + input +
                          " --threads 2 --out " + q(d / "local"));
  ASSERT_EQ(local.code, 0) << local.out;

  const CliRun sub = sh("WAIT=1 CITYLOD=" + std::string(CITYLOD_BINARY) + " " +
                        q(ex / "slurm" / "submit.sh") + " " + q(d / "slurm") + " 3 " + input);
  std::string logs;
  if (fs::exists(d / "slurm" / "logs"))
    for (const auto& e : fs::directory_iterator(d / "slurm" / "logs"))
      logs += e.path().string() + ":\n" + slurp(e.path());
  ASSERT_EQ(sub.code, 0) << sub.out << logs;
  int array_logs = 0;
  for (const auto& e : fs::directory_iterator(d / "slurm" / "logs"))
    array_logs += e.path().filename().string().rfind("citylod-lod-", 0) == 0;
  EXPECT_EQ(array_logs, 3) << logs;  // one per array task
  const auto a = tree(d / "local" / "tileset"), b = tree(d / "slurm" / "tileset");
  ASSERT_FALSE(a.empty());
  EXPECT_EQ(a.size(), b.size());
  for (const auto& [k, v] : a) {
    ASSERT_TRUE(b.count(k)) << k << " missing from the Slurm run";
    EXPECT_TRUE(b.at(k) == v) << k << " differs";
  }
}

}  // namespace
