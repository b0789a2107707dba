#pragma once
/// The one parallel-for helper (oneTBB stays inside parallel.cpp).
#include <cstddef>
#include <functional>
#include <memory>

namespace lp {

/// Calls body(i) for every i in [begin, end) on all allowed cores. Each index must
/// write only its own outputs; results are then independent of the thread count.
void ParallelFor(std::size_t begin, std::size_t end, const std::function<void(std::size_t)>& body);

/// Same, over contiguous chunks [b, e) of at most `grain` indices.
void ParallelForChunks(std::size_t begin, std::size_t end, std::size_t grain,
                       const std::function<void(std::size_t, std::size_t)>& body);

/// Limits the worker threads for its lifetime (0 = all cores).
class ThreadLimit {
 public:
  explicit ThreadLimit(int threads);
  ~ThreadLimit();
  ThreadLimit(const ThreadLimit&) = delete;
  ThreadLimit& operator=(const ThreadLimit&) = delete;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Background work that must not take the CPU from an interactive thread (the viewer's
/// window and its software rasterizer): lowers the OS priority (nice + `nice`, Linux
/// per-thread nice) of the calling thread and of every worker that joins its parallel
/// loops from now on. Lowering cannot be undone without privileges, so those workers stay
/// lower for the rest of the process; call it only where everything parallel may yield to
/// an interactive thread. Returns false where the priority could not be changed.
bool RunThisThreadInBackground(int nice = 10);

/// The calling thread's nice value (Linux per-thread; 0 elsewhere). For tests.
int ThisThreadNice();

/// Number of hardware threads.
int HardwareThreads();

}  // namespace lp
