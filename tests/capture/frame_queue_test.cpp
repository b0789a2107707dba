// The capture queue: drop-oldest under a slow consumer, counters, no deadlock on shutdown.
#include <atomic>
#include <chrono>
#include <thread>

#include <gtest/gtest.h>

#include "capture/frame_queue.h"
#include "tests/wait_for.h"

namespace lp {
namespace {

RgbdFrame Frame(std::int64_t i) {
  RgbdFrame f;
  f.index = i;
  return f;
}

TEST(FrameQueue, KeepsTheNewestWhenFull) {
  FrameQueue q(3);
  for (int i = 0; i < 10; ++i) EXPECT_TRUE(q.Push(Frame(i)));
  EXPECT_EQ(q.size(), 3u);
  for (int i = 7; i < 10; ++i) {
    auto f = q.Pop(0);
    ASSERT_TRUE(f);
    EXPECT_EQ(f->index, i);
  }
  EXPECT_FALSE(q.Pop(0.01));
  const QueueCounters c = q.counters();
  EXPECT_EQ(c.pushed, 10);
  EXPECT_EQ(c.dropped, 7);
  EXPECT_EQ(c.popped, 3);
}

TEST(FrameQueue, SlowConsumerLosesOldFramesNotNewOnes) {
  FrameQueue q(4);
  std::thread producer([&] {
    for (int i = 0; i < 2000; ++i) q.Push(Frame(i));
    q.Close();
  });
  // The consumer starts once the producer is a full queue and one frame ahead: from then
  // on a frame has been dropped, however the two threads were scheduled.
  EXPECT_TRUE(test::WaitFor([&] { return q.counters().pushed > 4; }, 60));
  std::int64_t last = -1, got = 0;
  while (auto f = q.Pop(60.0)) {
    EXPECT_GT(f->index, last);  // order kept
    last = f->index;
    ++got;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  producer.join();
  const QueueCounters c = q.counters();
  EXPECT_EQ(last, 1999);  // the newest frame always gets through
  EXPECT_EQ(c.pushed, 2000);
  EXPECT_EQ(c.popped, got);
  EXPECT_EQ(c.pushed, c.popped + c.dropped);
  EXPECT_GT(c.dropped, 0);
}

TEST(FrameQueue, CloseWakesABlockedConsumerAndRefusesPushes) {
  FrameQueue q(2);
  std::atomic<bool> returned{false};
  // Pop waits up to 200 s; woken by Close it returns long before. The bound below is half
  // that wait: it tells "woken" from "timed out" and does not time the wake-up itself.
  constexpr double kPopWait = 200;
  const auto start = std::chrono::steady_clock::now();
  std::thread consumer([&] {
    EXPECT_FALSE(q.Pop(kPopWait));
    returned = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));  // a chance to return too early
  EXPECT_FALSE(returned);
  q.Close();
  consumer.join();
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), kPopWait / 2)
      << "Close did not wake the consumer: it waited out its timeout";
  EXPECT_FALSE(q.Push(Frame(1)));
  EXPECT_TRUE(q.closed());
}

}  // namespace
}  // namespace lp
