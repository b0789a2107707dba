// RunThisThreadInBackground: the viewer's estimator yields the CPU to the window.
#include <atomic>
#include <mutex>
#include <set>
#include <thread>

#include <gtest/gtest.h>

#include "common/parallel.h"
#include "tests/wait_for.h"

namespace lp {
namespace {

/// Runs a parallel loop; returns the nice values of the threads that ran its iterations,
/// other than the calling one. The caller's iterations wait until a worker has run one:
/// when a worker gets a core depends on how busy the machine is, and a caller that ran
/// the whole loop alone would leave nothing to check.
std::multiset<int> WorkerNices(std::thread::id caller) {
  std::mutex m;
  std::multiset<int> nices;
  std::atomic<bool> worker_ran{false};
  ParallelFor(0, 256, [&](std::size_t) {
    if (std::this_thread::get_id() == caller) {
      test::WaitFor([&] { return worker_ran.load(); }, 120);
      return;
    }
    std::lock_guard<std::mutex> lock(m);
    nices.insert(ThisThreadNice());
    worker_ran = true;
  });
  return nices;
}

TEST(Parallel, BackgroundWorkLowersItsThreadAndItsLoopsWorkersNotTheCaller) {
  if (HardwareThreads() < 2) GTEST_SKIP() << "one hardware thread: no workers";
  const int before = ThisThreadNice();
  // Workers started from here first, at this thread's priority: only lowering them as they
  // join the background loop can change theirs (new threads would inherit it).
  const std::multiset<int> started = WorkerNices(std::this_thread::get_id());
  ASSERT_FALSE(started.empty());
  for (int n : started) EXPECT_EQ(n, before);
  int background = 0;
  std::multiset<int> workers;
  std::thread([&] {
    ASSERT_TRUE(RunThisThreadInBackground(10));
    background = ThisThreadNice();
    workers = WorkerNices(std::this_thread::get_id());
  }).join();
  EXPECT_EQ(background, std::min(19, before + 10));
  ASSERT_FALSE(workers.empty()) << "no worker joined the loop";
  for (int n : workers) EXPECT_GE(n, background);
  // The thread that started it keeps its priority.
  EXPECT_EQ(ThisThreadNice(), before);
}

}  // namespace
}  // namespace lp
