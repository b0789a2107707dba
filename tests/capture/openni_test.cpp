// Through the real OpenNI2 stack, no camera: the project's synthetic driver serves frames,
// OpenNI2's Recorder writes an .oni, its OniFile driver plays it back.
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "capture/openni.h"
#include "common/error.h"
#include "common/image_io.h"

namespace lp {
namespace {
namespace fs = std::filesystem;

constexpr int kFrames = 8, kW = 64, kH = 48;

DepthImage ServedDepth(int i) {
  DepthImage d{kW, kH, std::vector<std::uint16_t>(kW * kH)};
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) d.data[y * kW + x] = static_cast<std::uint16_t>((x + y) % 9 == 0 ? 0 : 800 + 37 * i + x * 3 + y);
  return d;
}

ImageRgb8 ServedColor(int i) {
  ImageRgb8 c{kW, kH, std::vector<std::uint8_t>(kW * kH * 3)};
  for (int p = 0; p < kW * kH; ++p) {
    c.data[3 * p] = static_cast<std::uint8_t>(i * 20);
    c.data[3 * p + 1] = static_cast<std::uint8_t>(p % 251);
    c.data[3 * p + 2] = static_cast<std::uint8_t>((p * 7) % 256);
  }
  return c;
}

class OpenNi : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lp_oni_" + std::to_string(::getpid()));
    fs::create_directories(dir_ / "frames" / "color");
    fs::create_directories(dir_ / "frames" / "depth");
    for (int i = 0; i < kFrames; ++i) {
      char name[32];
      std::snprintf(name, sizeof name, "%05d.png", i);
      WriteDepth16Png(dir_ / "frames" / "depth" / name, ServedDepth(i));
      WriteRgb8Png(dir_ / "frames" / "color" / name, ServedColor(i));
    }
    std::ofstream(dir_ / "frames" / "intrinsics.json") << R"({"fx": 52.5, "fy": 52.5, "cx": 31.5, "cy": 23.5, "width": 64, "height": 48})";
    uri_ = "lpsynth://" + (dir_ / "frames").string();
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  /// Which served frame a depth image is (-1: none).
  static int Which(const DepthImage& d) {
    for (int i = 0; i < kFrames; ++i)
      if (d.data == ServedDepth(i).data) return i;
    return -1;
  }
  fs::path dir_;
  std::string uri_;
};

TEST_F(OpenNi, RecordThroughTheRecorderAndReplayExactly) {
  const fs::path oni = dir_ / "rec.oni";
  RecordOptions ro;
  ro.uri = uri_;
  ro.frames = 12;
  const RecordResult rr = RecordOni(oni.string(), ro);
  EXPECT_EQ(rr.depth_frames, 12);
  EXPECT_GT(rr.color_frames, 0);
  ASSERT_TRUE(fs::exists(oni));
  ASSERT_NO_THROW(ValidateOniFile(oni.string()));

  auto src = OpenOniFile(oni.string());
  ASSERT_TRUE(src->FrameCount().has_value());
  EXPECT_GE(*src->FrameCount(), 10);
  RgbdFrame f;
  int n = 0, last = -1;
  while (src->Next(&f, 2.0) == SourceStatus::kFrame) {
    // Depth is stored losslessly and colour uncompressed: both exact, and paired.
    const int i = Which(f.depth);
    ASSERT_GE(i, 0) << "frame " << n << " is not a served depth image";
    EXPECT_EQ(f.color.data, ServedColor(i).data) << "colour not paired with its depth at frame " << n;
    if (last >= 0) {
      EXPECT_EQ(i, (last + 1) % kFrames);
    }
    last = i;
    EXPECT_EQ(f.depth.width, kW);
    EXPECT_NEAR(f.color_intrinsics.fx, 52.5, 0.01);
    ++n;
  }
  EXPECT_EQ(n, *src->FrameCount());
  // No end-of-file signal in OpenNI2: the source ends on the count, without hanging.
  EXPECT_EQ(src->Next(&f, 0.5), SourceStatus::kEnd);
  src->Rewind();
  ASSERT_EQ(src->Next(&f, 2.0), SourceStatus::kFrame);
}

TEST_F(OpenNi, CorruptTruncatedAndEmptyFilesAreClearErrors) {
  const fs::path oni = dir_ / "rec.oni";
  RecordOptions ro;
  ro.uri = uri_;
  ro.frames = 4;
  RecordOni(oni.string(), ro);
  std::ifstream in(oni, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  auto write = [&](const std::string& name, const std::string& content) {
    std::ofstream(dir_ / name, std::ios::binary) << content;
    return (dir_ / name).string();
  };
  std::string flipped = bytes;
  flipped[24] ^= 0x5a;  // the first record's magic
  std::string header_only = bytes.substr(0, 24);
  const std::string cases[] = {write("empty.oni", ""), write("cut.oni", bytes.substr(0, bytes.size() / 2)),
                               write("flipped.oni", flipped), write("header.oni", header_only),
                               write("text.oni", "this is not a recording")};
  for (const std::string& f : cases) {
    try {
      OpenOniFile(f);
      ADD_FAILURE() << f << " opened";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(f), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(OpenOniFile((dir_ / "missing.oni").string()), InputError);
}

TEST_F(OpenNi, UnpluggedMidStreamIsAClearErrorAndKeepsTheOldFile) {
  const fs::path oni = dir_ / "keep.oni";
  std::ofstream(oni) << "previous recording";
  RecordOptions ro;
  ro.uri = uri_ + "?unplug_after=5";
  ro.frames = 30;
  try {
    RecordOni(oni.string(), ro);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("unplugged"), std::string::npos) << e.what();
  }
  std::ifstream in(oni);
  std::string s;
  std::getline(in, s);
  EXPECT_EQ(s, "previous recording");
}

TEST_F(OpenNi, LiveDeviceLocksExposureReadsBackAndPairsFrames) {
  OpenNiDeviceOptions o;
  o.uri = uri_;
  o.width = kW;
  o.height = kH;
  o.exposure = 42;
  o.gain = 7;
  CameraControls applied;
  auto src = OpenOpenNiDevice(o, &applied);
  EXPECT_TRUE(applied.camera_settings);
  EXPECT_FALSE(applied.auto_exposure);
  EXPECT_FALSE(applied.auto_white_balance);
  EXPECT_EQ(applied.exposure, 42);
  EXPECT_EQ(applied.gain, 7);
  EXPECT_TRUE(applied.registered);
  RgbdFrame f;
  for (int n = 0; n < 5; ++n) {
    ASSERT_EQ(src->Next(&f, 2.0), SourceStatus::kFrame);
    const int i = Which(f.depth);
    ASSERT_GE(i, 0);
    EXPECT_EQ(f.color.data, ServedColor(i).data) << "depth and colour of different frames";
    EXPECT_TRUE(f.registered);
    EXPECT_NEAR(f.depth_timestamp, f.color_timestamp, 1e-9);
  }
  EXPECT_THROW(src->Rewind(), InputError);
}

TEST_F(OpenNi, LiveDeviceUnpluggedReportsDeviceLost) {
  OpenNiDeviceOptions o;
  o.uri = uri_ + "?unplug_after=3";
  o.width = kW;
  o.height = kH;
  auto src = OpenOpenNiDevice(o);
  RgbdFrame f;
  int frames = 0;
  SourceStatus s = SourceStatus::kFrame;
  for (int k = 0; k < 20 && s != SourceStatus::kDeviceLost; ++k) {
    s = src->Next(&f, 0.5);
    frames += s == SourceStatus::kFrame;
  }
  EXPECT_EQ(s, SourceStatus::kDeviceLost);
  EXPECT_LE(frames, 3);
}

TEST_F(OpenNi, AModeTheDeviceDoesNotHaveIsAClearError) {
  OpenNiDeviceOptions o;
  o.uri = uri_;  // 64x48 frames; asks for 640x480
  try {
    OpenOpenNiDevice(o);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("64x48@30"), std::string::npos) << e.what();
  }
}

TEST(OpenNiDevice, NoCameraSaysWhy) {
  RecordOptions ro;  // the first real device: there is none here
  try {
    RecordOni((fs::temp_directory_path() / "never.oni").string(), ro);
    GTEST_SKIP() << "a real camera is attached";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_TRUE(m.find("no depth camera on USB") != std::string::npos || m.find("no USB access") != std::string::npos ||
                m.find("may not open") != std::string::npos || m.find("driver") != std::string::npos)
        << m;
  }
}

}  // namespace
}  // namespace lp
