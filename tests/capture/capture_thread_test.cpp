// The capture thread: frames flow to the consumer, the end of a source closes the queue,
// Stop() ends a source that never ends, and a source that fails ends the thread with its
// message. Nothing here is timed (how long Stop takes: docs/benchmarks.md, Capture): the
// tests wait for states and counts, with limits that only a hang reaches.
#include <chrono>
#include <filesystem>
#include <thread>

#include <gtest/gtest.h>

#include "capture/capture_thread.h"
#include "common/error.h"
#include "tests/wait_for.h"

namespace lp {
namespace {
namespace fs = std::filesystem;

const fs::path kRedwood = fs::path(LIGHTPROBE_SOURCE_DIR) / "assets" / "rgbd" / "redwood_open3d" / "RGBD";

TEST(CaptureThread, AFiniteSourceEndsAndClosesTheQueue) {
  auto queue = std::make_shared<FrameQueue>(16);
  CaptureThread t(OpenDirectorySource(kRedwood.string()), queue);
  int n = 0;
  while (auto f = queue->Pop(60.0)) {
    EXPECT_EQ(f->index, n);
    ++n;
  }
  EXPECT_EQ(n, 5);
  t.Stop();
  const CaptureStats s = t.stats();
  EXPECT_FALSE(s.running);
  EXPECT_EQ(s.last_status, SourceStatus::kEnd);
  EXPECT_EQ(s.captured, 5);
  EXPECT_EQ(s.queue.dropped, 0);
}

TEST(CaptureThread, StopEndsASourceThatNeverEndsAndASlowConsumerCountsDrops) {
  auto queue = std::make_shared<FrameQueue>(2);
  DirectorySourceOptions o;
  o.loop = true;  // never ends by itself: Stop() returning at all is the check
  auto t = std::make_unique<CaptureThread>(OpenDirectorySource(kRedwood.string(), o), queue);
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(queue->Pop(60.0));
  // The consumer stops taking frames; once 3 more than it took were pushed, the queue
  // (capacity 2) has dropped one, however fast or slow the source ran.
  ASSERT_TRUE(test::WaitFor([&] { return t->stats().queue.pushed >= 3 + 3; }, 120));
  t->Stop();
  const CaptureStats s = t->stats();
  EXPECT_FALSE(s.running);
  EXPECT_GT(s.queue.dropped, 0);
  EXPECT_EQ(s.queue.pushed, s.captured);
  EXPECT_EQ(s.queue.pushed, s.queue.popped + s.queue.dropped + static_cast<std::int64_t>(queue->size()));
  EXPECT_TRUE(queue->closed());
  t.reset();  // destroying a stopped thread is fine
}

/// A source that delivers three frames and then fails, as a broken file would.
class FailingSource : public FrameSource {
 public:
  std::string Describe() const override { return "failing"; }
  SourceStatus Next(RgbdFrame* f, double) override {
    if (n_ == 3) throw InputError("frame 3: cannot decode image");
    f->index = n_++;
    return SourceStatus::kFrame;
  }
  void Rewind() override { n_ = 0; }

 private:
  int n_ = 0;
};

TEST(CaptureThread, ASourceThatThrowsEndsTheThreadWithItsMessage) {
  auto queue = std::make_shared<FrameQueue>(8);
  CaptureThread t(std::make_unique<FailingSource>(), queue);
  int n = 0;
  while (queue->Pop(60.0)) ++n;
  EXPECT_EQ(n, 3);
  t.Stop();
  EXPECT_NE(t.stats().error.find("cannot decode"), std::string::npos);
}

/// Which frame of the Redwood directory a depth image is (-1: none).
int WhichRedwoodFrame(const DepthImage& d) {
  auto src = OpenDirectorySource(kRedwood.string());
  RgbdFrame f;
  for (int i = 0; src->Next(&f) == SourceStatus::kFrame; ++i)
    if (f.depth.data == d.data) return i;
  return -1;
}

// A viewer's play / pause / seek bar: paused reads nothing, a seek (while paused) moves
// to that frame, and with hold_at_end the thread waits at the end for another seek.
TEST(CaptureThread, PauseSeekAndHoldAtTheEnd) {
  auto queue = std::make_shared<FrameQueue>(16);
  CaptureThread t(OpenDirectorySource(kRedwood.string()), queue, true);
  t.Pause(true);
  // Once the thread says it is paused, it reads nothing until resumed.
  ASSERT_TRUE(test::WaitFor([&] { return t.stats().paused; }, 60));
  const std::int64_t before = t.stats().captured;
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // a chance to read while paused
  EXPECT_EQ(t.stats().captured, before) << "a paused thread read frames";
  EXPECT_TRUE(t.stats().paused);
  while (queue->Pop(0)) {
  }
  t.Seek(3);
  t.Pause(false);
  for (int expect : {3, 4}) {
    auto f = queue->Pop(60.0);
    ASSERT_TRUE(f);
    EXPECT_EQ(WhichRedwoodFrame(f->depth), expect);
  }
  // At the end: held (running, paused, queue open) until a seek.
  ASSERT_TRUE(test::WaitFor([&] { const CaptureStats s = t.stats(); return s.paused && s.position == 5; }, 60))
      << "not held at the end";
  EXPECT_TRUE(t.stats().running);
  EXPECT_FALSE(queue->closed());
  EXPECT_FALSE(queue->Pop(0.2)) << "a frame after the end";
  t.Seek(1);
  auto f = queue->Pop(60.0);
  ASSERT_TRUE(f);
  EXPECT_EQ(WhichRedwoodFrame(f->depth), 1);
  t.Seek(99);  // past the end: the source refuses, the thread ends with the reason
  while (queue->Pop(60.0)) {
  }
  t.Stop();
  EXPECT_NE(t.stats().error.find("cannot seek to frame 99"), std::string::npos) << t.stats().error;
}

/// Frames every 5 ms whose colour repeats every second frame (a colour stream at half rate).
class HalfRateColorSource : public FrameSource {
 public:
  std::string Describe() const override { return "half-rate colour"; }
  SourceStatus Next(RgbdFrame* f, double) override {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    f->index = n_;
    f->depth_timestamp = n_ * 0.005;
    f->color_timestamp = (n_ / 2) * 0.01;
    ++n_;
    return SourceStatus::kFrame;
  }
  void Rewind() override { n_ = 0; }

 private:
  int n_ = 0;
};

TEST(CaptureThread, CountsFramesPerStream) {
  auto queue = std::make_shared<FrameQueue>(4);
  CaptureThread t(std::make_unique<HalfRateColorSource>(), queue);
  // The rates are published when a window of at least a second ends; nobody pops, so once
  // more than 4 frames were pushed the queue has dropped the oldest.
  ASSERT_TRUE(test::WaitFor([&] { const CaptureStats s = t.stats(); return s.depth_fps > 0 && s.queue.pushed > 4; }, 120));
  const CaptureStats s = t.stats();
  t.Stop();
  // Over a window of N frames (N >= depth_fps: the window is a second or longer) every
  // frame has a new depth image and every second one a new colour image: the colour count
  // is N / 2 rounded either way, whatever N the machine allowed.
  EXPECT_NEAR(s.color_fps / s.depth_fps, 0.5, 0.5 / s.depth_fps + 1e-9);
  EXPECT_NEAR(s.fps, s.depth_fps, 1e-9);
  EXPECT_GT(s.queue.dropped, 0) << "nobody pops: the queue drops the oldest";
}

}  // namespace
}  // namespace lp
