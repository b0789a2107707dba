#pragma once
// Waiting in tests without measuring time: WaitFor polls a condition until it holds, and
// its limit only stops a test whose condition never comes (a hang), never one that is
// merely slow on a busy machine. Keep limits generous (tens to hundreds of seconds); a
// test asserts what happened (order, counts, states), not how long it took.
#include <chrono>
#include <thread>
#include <utility>

namespace lp::test {

/// Polls `done` every 20 ms until it returns true (true) or `limit_seconds` passed (false).
template <typename F>
bool WaitFor(F done, double limit_seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(limit_seconds);
  while (std::chrono::steady_clock::now() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return done();
}

/// For work whose speed depends on the machine (an estimate at a lower OS priority runs
/// ~10 times slower beside a busy loop): waits while `progress()` (any value with !=)
/// keeps changing. True once `done()`; false once `progress()` has not changed for
/// `stall_seconds`, a hang however slowly the machine runs (the test's own timeout is
/// the last limit).
template <typename Done, typename Progress>
bool WaitWhileProgressing(Done done, Progress progress, double stall_seconds) {
  using Clock = std::chrono::steady_clock;
  auto last = progress();
  auto changed = Clock::now();
  for (;;) {
    if (done()) return true;
    auto now = progress();
    if (now != last) {
      last = std::move(now);
      changed = Clock::now();
    } else if (Clock::now() - changed > std::chrono::duration<double>(stall_seconds)) {
      return done();
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

}  // namespace lp::test
