#include "common/parallel.h"

#include <algorithm>
#include <cerrno>
#include <thread>

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_scheduler_observer.h>

namespace lp {

void ParallelFor(std::size_t begin, std::size_t end, const std::function<void(std::size_t)>& body) {
  if (begin >= end) return;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(begin, end),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i != r.end(); ++i) body(i);
                    });
}

void ParallelForChunks(std::size_t begin, std::size_t end, std::size_t grain,
                       const std::function<void(std::size_t, std::size_t)>& body) {
  if (begin >= end) return;
  if (grain == 0) grain = 1;
  const std::size_t chunks = (end - begin + grain - 1) / grain;
  tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
    const std::size_t b = begin + c * grain;
    const std::size_t e = std::min(end, b + grain);
    body(b, e);
  });
}

struct ThreadLimit::Impl {
  std::unique_ptr<tbb::global_control> control;
};

ThreadLimit::ThreadLimit(int threads) : impl_(std::make_unique<Impl>()) {
  if (threads > 0)
    impl_->control = std::make_unique<tbb::global_control>(
        tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
}
ThreadLimit::~ThreadLimit() = default;

namespace {

#ifdef __linux__
pid_t ThreadId() { return static_cast<pid_t>(syscall(SYS_gettid)); }

/// Lowers this thread's priority to at least `nice` (never raises it).
bool LowerThisThread(int nice) {
  errno = 0;
  const int now = getpriority(PRIO_PROCESS, static_cast<id_t>(ThreadId()));
  if (errno != 0) return false;
  if (now >= nice) return true;
  return setpriority(PRIO_PROCESS, static_cast<id_t>(ThreadId()), nice) == 0;
}

/// Lowers every worker thread that enters the arena of the thread that created it.
class BackgroundObserver : public tbb::task_scheduler_observer {
 public:
  explicit BackgroundObserver(int nice) : nice_(nice) { observe(true); }
  ~BackgroundObserver() override { observe(false); }
  void on_scheduler_entry(bool is_worker) override {
    if (is_worker) LowerThisThread(nice_);
  }

 private:
  int nice_;
};
#endif

}  // namespace

bool RunThisThreadInBackground(int nice) {
#ifdef __linux__
  const int target = std::min(19, ThisThreadNice() + nice);
  if (!LowerThisThread(target)) return false;
  // One observer per thread: the workers of this thread's (implicit) arena.
  thread_local std::unique_ptr<BackgroundObserver> observer;
  if (!observer) observer = std::make_unique<BackgroundObserver>(target);
  return true;
#else
  (void)nice;
  return false;
#endif
}

int ThisThreadNice() {
#ifdef __linux__
  errno = 0;
  const int now = getpriority(PRIO_PROCESS, static_cast<id_t>(ThreadId()));
  return errno == 0 ? now : 0;
#else
  return 0;
#endif
}

int HardwareThreads() {
  const unsigned n = std::thread::hardware_concurrency();
  return n == 0 ? 1 : static_cast<int>(n);
}

}  // namespace lp
