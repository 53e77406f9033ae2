// Crash isolation for the LOD stage. The work runs in a
// forked child; when the child dies from a signal (a crash in some building),
// the building(s) it was running are marked — `.crashed` when only one was
// running, `.suspect` when several were (they are then retried one at a time)
// — and the child is started again; finished buildings are not recomputed.
// The child dies with its supervisor (PR_SET_PDEATHSIG: SIGKILL, even when the
// supervisor is SIGKILLed), and SIGTERM / SIGINT / SIGHUP sent to the
// supervisor are forwarded to it; the supervisor then dies of the same signal.
#pragma once

#include <functional>
#include <string>

namespace citylod::tiler {

/// Runs `work` in a child process until it exits normally; returns its exit
/// code. `work_dir` holds the lod/<id>.running markers. Gives up after
/// `max_restarts` crashes (returns 1). `work` must not start an OpenMP team
/// with more than one thread when this process has run one before the fork
/// (libgomp's pool does not survive fork); run_lod_stage() uses std::threads.
/// `crashes` (if given) receives the number of restarts after a crash.
int supervise(const std::string& work_dir, const std::function<int()>& work,
              int max_restarts = 1000, int* crashes = nullptr);

}  // namespace citylod::tiler
