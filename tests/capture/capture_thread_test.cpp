// The capture thread: frames flow to the consumer, the end of a source closes the queue,
// Stop() returns promptly, and a source that fails ends the thread with its message.
#include <chrono>
#include <filesystem>
#include <thread>

#include <gtest/gtest.h>

#include "capture/capture_thread.h"
#include "common/error.h"

namespace lp {
namespace {
namespace fs = std::filesystem;

const fs::path kRedwood = fs::path(LIGHTPROBE_SOURCE_DIR) / ".." / "shared" / "data" / "rgbd" / "redwood_open3d" / "RGBD";

TEST(CaptureThread, AFiniteSourceEndsAndClosesTheQueue) {
  if (!fs::exists(kRedwood)) GTEST_SKIP() << "shared data not present";
  auto queue = std::make_shared<FrameQueue>(16);
  CaptureThread t(OpenDirectorySource(kRedwood.string()), queue);
  int n = 0;
  while (auto f = queue->Pop(10.0)) {
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

TEST(CaptureThread, StopWithASlowConsumerIsPromptAndCountsDrops) {
  if (!fs::exists(kRedwood)) GTEST_SKIP() << "shared data not present";
  auto queue = std::make_shared<FrameQueue>(2);
  DirectorySourceOptions o;
  o.loop = true;  // never ends by itself
  auto t = std::make_unique<CaptureThread>(OpenDirectorySource(kRedwood.string(), o), queue);
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(queue->Pop(10.0));
    std::this_thread::sleep_for(std::chrono::milliseconds(100));  // slower than the source
  }
  const auto start = std::chrono::steady_clock::now();
  t->Stop();
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 2.0);
  const CaptureStats s = t->stats();
  EXPECT_FALSE(s.running);
  EXPECT_GT(s.queue.dropped, 0);
  EXPECT_EQ(s.queue.pushed, s.captured);
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
  while (queue->Pop(10.0)) ++n;
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
  if (!fs::exists(kRedwood)) GTEST_SKIP() << "shared data not present";
  auto queue = std::make_shared<FrameQueue>(16);
  CaptureThread t(OpenDirectorySource(kRedwood.string()), queue, true);
  t.Pause(true);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const std::int64_t before = t.stats().captured;
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_EQ(t.stats().captured, before) << "a paused thread read frames";
  EXPECT_TRUE(t.stats().paused);
  while (queue->Pop(0.01)) {
  }
  t.Seek(3);
  t.Pause(false);
  for (int expect : {3, 4}) {
    auto f = queue->Pop(10.0);
    ASSERT_TRUE(f);
    EXPECT_EQ(WhichRedwoodFrame(f->depth), expect);
  }
  // At the end: held (running, paused, queue open) until a seek.
  EXPECT_FALSE(queue->Pop(0.5));
  EXPECT_TRUE(t.stats().running);
  EXPECT_TRUE(t.stats().paused);
  EXPECT_EQ(t.stats().position, 5);
  t.Seek(1);
  auto f = queue->Pop(10.0);
  ASSERT_TRUE(f);
  EXPECT_EQ(WhichRedwoodFrame(f->depth), 1);
  t.Seek(99);  // past the end: the source refuses, the thread ends with the reason
  while (queue->Pop(10.0)) {
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
  std::this_thread::sleep_for(std::chrono::milliseconds(2300));
  const CaptureStats s = t.stats();
  t.Stop();
  ASSERT_GT(s.depth_fps, 0);
  EXPECT_NEAR(s.color_fps / s.depth_fps, 0.5, 0.05);
  EXPECT_NEAR(s.fps, s.depth_fps, 1e-9);
  EXPECT_GT(s.queue.dropped, 0) << "nobody pops: the queue drops the oldest";
}

}  // namespace
}  // namespace lp
