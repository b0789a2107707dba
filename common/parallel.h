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

/// Number of hardware threads.
int HardwareThreads();

}  // namespace lp
