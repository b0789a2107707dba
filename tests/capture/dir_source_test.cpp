// Directory sources on the real sequences in assets/rgbd (Redwood) and tests/data/rgbd (joinMap) and a TUM
// layout built from TUM's own frame: depth scale, intrinsics, poses, clear errors.
#include <algorithm>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "capture/frame_source.h"
#include "capture/trajectory.h"
#include "capture/tum_index.h"
#include "common/error.h"
#include "common/image_io.h"

namespace lp {
namespace {
namespace fs = std::filesystem;

const fs::path kAssets = fs::path(LIGHTPROBE_SOURCE_DIR) / "assets" / "rgbd";
const fs::path kTestData = fs::path(LIGHTPROBE_SOURCE_DIR) / "tests" / "data" / "rgbd";

std::uint16_t MedianValid(const DepthImage& d) {
  std::vector<std::uint16_t> v;
  for (auto x : d.data)
    if (x) v.push_back(x);
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

std::vector<RgbdFrame> ReadAll(FrameSource& s) {
  std::vector<RgbdFrame> out;
  RgbdFrame f;
  while (s.Next(&f) == SourceStatus::kFrame) out.push_back(f);
  return out;
}

TEST(DirectorySource, RedwoodReplaysWithIntrinsicsAndPoses) {
  const fs::path dir = kAssets / "redwood_open3d" / "RGBD";
  auto s = OpenDirectorySource(dir.string());
  ASSERT_EQ(s->FrameCount(), 5);
  const auto frames = ReadAll(*s);
  ASSERT_EQ(frames.size(), 5u);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const RgbdFrame& f = frames[i];
    EXPECT_EQ(f.index, static_cast<std::int64_t>(i));
    EXPECT_EQ(f.color.width, 640);
    EXPECT_EQ(f.depth.height, 480);
    EXPECT_DOUBLE_EQ(f.color_intrinsics.fx, 525.0);
    EXPECT_DOUBLE_EQ(f.color_intrinsics.cx, 319.5);
    EXPECT_TRUE(f.registered);
    ASSERT_TRUE(f.world_from_camera.has_value());
    // An indoor scene in millimetres: a median between 0.3 m and 6 m.
    const auto med = MedianValid(f.depth);
    EXPECT_GT(med, 300);
    EXPECT_LT(med, 6000);
  }
  // The first pose of trajectory.log.
  EXPECT_NEAR((*frames[0].world_from_camera)(0, 0), -0.2739592186924325, 1e-12);
  EXPECT_NEAR((*frames[0].world_from_camera)(2, 3), 2.1264800183565487, 1e-12);
  RgbdFrame f;
  EXPECT_EQ(s->Next(&f), SourceStatus::kEnd);
  s->Rewind();
  ASSERT_EQ(s->Next(&f), SourceStatus::kFrame);
  EXPECT_EQ(f.depth.data, frames[0].depth.data);
}

TEST(DirectorySource, JoinMapReplaysWithPoses) {
  const fs::path dir = kTestData / "joinmap_slambook";
  auto s = OpenDirectorySource(dir.string());
  const auto frames = ReadAll(*s);
  ASSERT_EQ(frames.size(), 5u);
  ASSERT_TRUE(frames[0].world_from_camera.has_value());
  EXPECT_NEAR((*frames[0].world_from_camera)(0, 3), -0.228993, 1e-9);
  // slambook's camera, not the PrimeSense default.
  EXPECT_EQ(frames[0].depth_intrinsics.fx, 518.0);
  EXPECT_EQ(frames[0].depth_intrinsics.cy, 253.5);
  const auto med = MedianValid(frames[0].depth);
  EXPECT_GT(med, 300);
  EXPECT_LT(med, 8000);
}

class TumDir : public ::testing::Test {
 protected:
  void SetUp() override {
    src_ = kTestData / "tum_one_frame";
    dir_ = fs::temp_directory_path() / ("lp_tum_" + std::to_string(::getpid()));
    fs::create_directories(dir_ / "rgb");
    fs::create_directories(dir_ / "depth");
    fs::copy_file(src_ / "TUM_color.png", dir_ / "rgb" / "1.000000.png");
    fs::copy_file(src_ / "TUM_depth.png", dir_ / "depth" / "1.010000.png");
    std::ofstream(dir_ / "rgb.txt") << "# colour images\n# file: test\n# timestamp filename\n1.000000 rgb/1.000000.png\n";
    std::ofstream(dir_ / "depth.txt") << "# depth maps\n1.010000 depth/1.010000.png\n";
  }
  void TearDown() override {
    std::error_code ec;
    if (!dir_.empty()) fs::remove_all(dir_, ec);
  }
  fs::path src_, dir_;
};

TEST_F(TumDir, DepthIsFiveThousandPerMetre) {
  auto s = OpenDirectorySource(dir_.string());
  RgbdFrame f;
  ASSERT_EQ(s->Next(&f), SourceStatus::kFrame);
  const DepthImage raw = ReadDepth16(src_ / "TUM_depth.png");
  ASSERT_EQ(f.depth.data.size(), raw.data.size());
  for (std::size_t i = 0; i < raw.data.size(); i += 101)
    EXPECT_EQ(f.depth.data[i], static_cast<std::uint16_t>(std::lround(raw.data[i] / 5.0))) << i;
  EXPECT_DOUBLE_EQ(f.color_timestamp, 1.0);
  EXPECT_DOUBLE_EQ(f.depth_timestamp, 1.01);
  EXPECT_DOUBLE_EQ(f.depth_intrinsics.fy, 525.0);
  EXPECT_FALSE(f.world_from_camera.has_value());
  EXPECT_EQ(s->Next(&f), SourceStatus::kEnd);
}

TEST_F(TumDir, AnIndexNamingAMissingFileIsAClearError) {
  std::ofstream(dir_ / "depth.txt", std::ios::app) << "1.033 depth/missing.png\n";
  std::ofstream(dir_ / "rgb.txt", std::ios::app) << "1.033 rgb/1.000000.png\n";
  try {
    OpenDirectorySource(dir_.string());
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.png"), std::string::npos) << e.what();
  }
}

TEST(TumIndex, EachDepthFrameTakesTheNearestColourFrameWithin20Ms) {
  const auto rgb = ParseTumList("# colour\n1.000 rgb/a.png\n1.030 rgb/b.png\n1.030 rgb/b2.png\n2.000 rgb/c.png\n", "rgb.txt");
  const auto depth = ParseTumList("0.995 d/1.png\n1.016 d/2.png\n1.040 d/3.png\n1.500 d/4.png\n1.9801 d/5.png\n", "depth.txt");
  const auto pairs = PairTumLists(rgb, depth);
  // d/1: a (5 ms); d/2: b (14 ms, nearer than a's 16 ms; b listed before b2 at the same
  // time); d/3: b (10 ms); d/4: none within 20 ms; d/5: c (19.9 ms).
  ASSERT_EQ(pairs.size(), 4u);
  EXPECT_EQ(pairs[0].color, "rgb/a.png");
  EXPECT_EQ(pairs[1].color, "rgb/b.png");
  EXPECT_EQ(pairs[1].depth, "d/2.png");
  EXPECT_EQ(pairs[2].color, "rgb/b.png");
  EXPECT_EQ(pairs[3].color, "rgb/c.png");
  EXPECT_DOUBLE_EQ(pairs[3].depth_time, 1.9801);
  // The same pairs whatever order the colour list is in.
  const auto shuffled = ParseTumList("2.000 rgb/c.png\n1.030 rgb/b.png\n1.000 rgb/a.png\n1.030 rgb/b2.png\n", "rgb.txt");
  const auto again = PairTumLists(shuffled, depth);
  ASSERT_EQ(again.size(), 4u);
  for (std::size_t i = 0; i < again.size(); ++i) EXPECT_EQ(again[i].color, pairs[i].color) << i;
  EXPECT_THROW(ParseTumList("1.0\n", "rgb.txt"), InputError);
  EXPECT_THROW(ParseTumAssociations("1.0 a.png 1.0\n", "associations.txt"), InputError);
  EXPECT_EQ(ParseTumAssociations("1.0 a.png 1.01 b.png\n", "associations.txt").at(0).depth, "b.png");
}

TEST(PoseLogs, MalformedLinesNameTheFileAndLine) {
  EXPECT_EQ(ParsePoseTxt("0 0 0 0 0 0 1\n1 2 3 0 0 0 2\n", "pose.txt").size(), 2u);
  auto error = [](auto f) {
    try {
      f();
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(error([] { ParsePoseTxt("0 0 0 0 0 0 1\n0 0 0 0 0 0 0\n", "pose.txt"); }).find("pose.txt: line 2"),
            std::string::npos);
  EXPECT_NE(error([] { ParsePoseTxt("0 0 0 1e300 1e300 0 1\n", "pose.txt"); }).find("quaternion"), std::string::npos);
  EXPECT_NE(error([] { ParsePoseTxt("0 0 0 0 0 nan 1\n", "pose.txt"); }).find("not a number"), std::string::npos);
  EXPECT_NE(error([] { ParseTrajectoryLog("0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n", "t.log"); }).find("t.log"),
            std::string::npos);
  EXPECT_EQ(ParseTrajectoryLog("0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n", "t.log").size(), 1u);
}

TEST(DirectorySource, UnknownLayoutAndMissingDirectoryAreClearErrors) {
  EXPECT_THROW(OpenDirectorySource("/nonexistent/frames"), InputError);
  EXPECT_THROW(OpenDirectorySource(fs::temp_directory_path().string()), InputError);
}

}  // namespace
}  // namespace lp
