// Scene-bundle and PLY input: round trips, and clear errors on bad input.
#include <cerrno>
#include <filesystem>
#include <vector>
#include <fstream>

#include <gtest/gtest.h>
#include <cmath>

#include "common/atomic_file.h"
#include "common/error.h"
#include "common/image_io.h"
#include "estimation/error_display.h"
#include "estimation/estimator.h"
#include "scene/scene_bundle.h"
#include "tests/test_util.h"

namespace lp {
namespace {

using test::ErrorOf;
namespace fs = std::filesystem;

/// The directories TempDir made, removed when the test program's tests end (each test
/// runs as its own process under ctest: nothing is left in the temporary directory).
class TempDirs : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ec;
    for (const fs::path& d : made) fs::remove_all(d, ec);
  }
  static inline std::vector<fs::path> made;
};
const ::testing::Environment* const kTempDirs = ::testing::AddGlobalTestEnvironment(new TempDirs);

fs::path TempDir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("lp_io_test_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  TempDirs::made.push_back(d);
  return d;
}

SceneBundle SmallBundle() {
  SceneBundle b;
  b.mesh = test::Plane(4, 0.5);
  View v = test::BlankView(test::LookAt({0, 0, 2}, {0, 0, 0}, 16, 12, 40));
  for (std::size_t i = 0; i < v.image.data.size(); ++i) v.image.data[i] = 0.25f;
  b.views.push_back(v);
  return b;
}

TEST(Bundle, RoundTrip) {
  const fs::path d = TempDir("rt") / "scene";
  SceneBundle b = SmallBundle();
  b.views[0].valid[3] = 0;
  // Intrinsics with nothing symmetric about them: a swapped fx/fy or cx/cy shows.
  Camera& k = b.views[0].camera;
  k.fx = 17.25;
  k.fy = 19.5;
  k.cx = 7.125;
  k.cy = 5.0625;
  b.up = Eigen::Vector3d(0.1, 0.2, 1).normalized();
  WriteSceneBundle(d, b);
  const SceneBundle r = LoadSceneBundle(d);
  ASSERT_EQ(r.views.size(), 1u);
  const Camera& rk = r.views[0].camera;
  EXPECT_EQ(rk.width, 16);
  EXPECT_EQ(rk.height, 12);
  EXPECT_EQ(rk.fx, 17.25);
  EXPECT_EQ(rk.fy, 19.5);
  EXPECT_EQ(rk.cx, 7.125);
  EXPECT_EQ(rk.cy, 5.0625);
  EXPECT_NEAR((r.up - b.up).norm(), 0, 1e-12);
  EXPECT_EQ(r.views[0].masked_out, 1);
  EXPECT_NEAR(r.views[0].image.data[0], 0.25f, 1e-6);
  EXPECT_EQ(r.mesh.triangles.size(), 2u);
  EXPECT_NEAR(r.mesh.albedo[0].x(), 0.5f, 0.01f);  // through 8-bit sRGB
  EXPECT_TRUE((r.views[0].camera.world_from_camera - b.views[0].camera.world_from_camera).norm() < 1e-12);
}

TEST(Bundle, ExtraFilesAreWrittenAndReplacedWithTheBundle) {
  const fs::path d = TempDir("extra") / "scene";
  SceneBundle b = SmallBundle();
  b.extra_files = {{"reconstruction.csv", "frame\n0\n"}, {"calibration.json", "{}\n"}};
  WriteSceneBundle(d, b);
  EXPECT_EQ(ReadTextFile(d / "reconstruction.csv"), "frame\n0\n");
  EXPECT_EQ(ReadTextFile(d / "calibration.json"), "{}\n");
  // A bundle written without them replaces them too: no stale calibration is left behind.
  SceneBundle plain = SmallBundle();
  plain.extra_files = {{"reconstruction.csv", "frame\n1\n"}};
  WriteSceneBundle(d, plain);
  EXPECT_EQ(ReadTextFile(d / "reconstruction.csv"), "frame\n1\n");
  EXPECT_FALSE(fs::exists(d / "calibration.json"));
  // A write that fails half way leaves the bundle as it was, and no temporary directory.
  SceneBundle bad = SmallBundle();
  bad.extra_files = {{"trajectory.log", "x"}, {"../escape.txt", "x"}};
  EXPECT_THROW(WriteSceneBundle(d, bad), std::exception);
  EXPECT_EQ(ReadTextFile(d / "reconstruction.csv"), "frame\n1\n");
  EXPECT_FALSE(fs::exists(d / "trajectory.log"));
  EXPECT_FALSE(fs::exists(d.parent_path() / "escape.txt"));
  EXPECT_FALSE(fs::exists(d.parent_path() / ".tmp.scene"));
  EXPECT_NO_THROW(LoadSceneBundle(d));
}

TEST(Bundle, ClearErrorsNameTheFile) {
  const fs::path d = TempDir("err") / "scene";
  EXPECT_NE(ErrorOf([&] { LoadSceneBundle(d); }).find("not found"), std::string::npos);
  WriteSceneBundle(d, SmallBundle());
  // Malformed JSON.
  WriteTextAtomically(d / "scene.json", "{\"views\": [");
  EXPECT_NE(ErrorOf([&] { LoadSceneBundle(d); }).find("scene.json: malformed JSON"), std::string::npos);
  // Size mismatch.
  WriteSceneBundle(d, SmallBundle());
  std::string json = ReadTextFile(d / "scene.json");
  json.replace(json.find("\"width\": 16"), 11, "\"width\": 17");
  WriteTextAtomically(d / "scene.json", json);
  EXPECT_NE(ErrorOf([&] { LoadSceneBundle(d); }).find("view0.exr: image is 16x12 but scene.json says 17x12"),
            std::string::npos);
  // Missing mesh.
  WriteSceneBundle(d, SmallBundle());
  fs::remove(d / "mesh.ply");
  EXPECT_NE(ErrorOf([&] { LoadSceneBundle(d); }).find("mesh.ply: file not found"), std::string::npos);
  // Corrupt image.
  WriteSceneBundle(d, SmallBundle());
  WriteTextAtomically(d / "view0.exr", "not an exr");
  EXPECT_NE(ErrorOf([&] { LoadSceneBundle(d); }).find("view0.exr: cannot decode"), std::string::npos);
}

TEST(Bundle, NonFiniteAndNegativePixelsAreMaskedAndCounted) {
  const fs::path d = TempDir("nan") / "scene";
  SceneBundle b = SmallBundle();
  b.views[0].image.data[0] = std::nanf("");
  b.views[0].image.data[4] = std::numeric_limits<float>::infinity();
  b.views[0].image.data[8] = -1.f;
  WriteSceneBundle(d, b);
  const SceneBundle r = LoadSceneBundle(d);
  EXPECT_EQ(r.views[0].non_finite, 2);
  EXPECT_EQ(r.views[0].negative, 1);
  EXPECT_EQ(r.views[0].valid[0], 0);
  EXPECT_EQ(r.views[0].valid[1], 0);
  EXPECT_EQ(r.views[0].valid[2], 0);
  EXPECT_EQ(r.views[0].valid[3], 1);
}

// The one white level behind render_view*.png, error_view*.png and the viewer's error
// shading: the 99th-percentile luminance of the valid pixels; masked pixels do not count.
TEST(Bundle, WhiteLevelIsThe99thPercentileOfTheValidPixels) {
  View v;
  v.image = ImageRGB(1000, 2);
  v.valid.assign(2000, 0);
  for (int i = 0; i < 1000; ++i) {
    // grey 1 .. 1000, shuffled (a multiplier coprime to 1000)
    for (int c = 0; c < 3; ++c) v.image.data[3 * i + c] = static_cast<float>((i * 37) % 1000 + 1);
    v.valid[i] = 1;
  }
  for (int i = 1000; i < 2000; ++i)
    for (int c = 0; c < 3; ++c) v.image.data[3 * i + c] = 5000.f;  // masked: ignored
  EXPECT_NEAR(WhiteLevel(v), 991.f, 1e-3);  // index 990 of 1000 sorted values: not the maximum
  for (int i = 0; i < 1000; ++i) v.valid[i] = (i * 37) % 1000 < 500;  // the values 1 .. 500
  EXPECT_NEAR(WhiteLevel(v), 496.f, 1e-3);
  std::fill(v.valid.begin(), v.valid.end(), 0);
  EXPECT_EQ(WhiteLevel(v), 1.f);
  const float a[3] = {1, 2, 3}, b[3] = {1, 2, 0};
  EXPECT_NEAR(PixelError(a, b), std::sqrt(3.f), 1e-6);
  // The error image: PixelError where valid, -1 (shown black) where masked.
  v.valid[0] = 1;
  ImageRGB render = v.image;
  render.data[0] += 3;
  const std::vector<float> err = ErrorImage(render, v);
  ASSERT_EQ(err.size(), v.image.pixels());
  EXPECT_NEAR(err[0], std::sqrt(3.f), 1e-5);
  EXPECT_EQ(err[1], -1.f);
  const ImageRgb8 heat = Heatmap(render.width, render.height, err, std::sqrt(3.f));
  EXPECT_GT(heat.data[0], 200);  // top of the scale: viridis yellow
  EXPECT_EQ(heat.data[3] + heat.data[4] + heat.data[5], 0);  // masked: black
}

TEST(Bundle, EverythingMaskedIsAClearError) {
  const fs::path d = TempDir("mask") / "scene";
  SceneBundle b = SmallBundle();
  std::fill(b.views[0].valid.begin(), b.views[0].valid.end(), 0);
  WriteSceneBundle(d, b);
  const SceneBundle r = LoadSceneBundle(d);
  EXPECT_NE(ErrorOf([&] { Estimate(r, EstimateOptions()); }).find("every pixel of every view is masked"),
            std::string::npos);
}

TEST(Ply, DegenerateAndEmptyMeshes) {
  Mesh m = test::Plane(1, 0.5);
  m.triangles.push_back({0, 0, 1});  // repeated index
  m.positions.push_back({5, 5, 5});
  m.normals.push_back({0, 0, 1});
  m.albedo.push_back({1, 1, 1});
  m.triangles.push_back({0, 1, 4});  // fine
  m.positions.push_back({0, 0, 0});
  m.normals.push_back({0, 0, 1});
  m.albedo.push_back({1, 1, 1});
  m.triangles.push_back({0, 5, 0});  // repeated
  EXPECT_EQ(SanitizeMesh(&m, "m"), 2);
  Mesh flat;
  flat.positions = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
  flat.triangles = {{0, 1, 2}};
  EXPECT_NE(ErrorOf([&] { SanitizeMesh(&flat, "flat.ply"); }).find("flat.ply: mesh has no non-degenerate"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { ParsePly("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
                                   "property float z\nelement face 0\nproperty list uchar int vertex_indices\n"
                                   "end_header\n",
                                   "empty.ply");
                          Mesh e = ParsePly("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty "
                                            "float y\nproperty float z\nelement face 0\nproperty list uchar int "
                                            "vertex_indices\nend_header\n",
                                            "empty.ply");
                          SanitizeMesh(&e, "empty.ply"); })
                .find("empty.ply: mesh has no vertices"),
            std::string::npos);
}

Mesh ReadPlyBack(const Mesh& m) {
  const fs::path d = TempDir("plyback");
  WritePly(d / "m.ply", m);
  return ReadPly(d / "m.ply");
}

TEST(Ply, AsciiAndBinaryAgreeAndBadFilesAreRejected) {
  const std::string ascii =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "property uchar red\nproperty uchar green\nproperty uchar blue\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0 0 0 255\n3 0 1 2\n";
  const Mesh a = ParsePly(ascii, "a.ply");
  ASSERT_EQ(a.positions.size(), 3u);
  EXPECT_FLOAT_EQ(a.albedo[0].x(), 1.f);
  const fs::path d = TempDir("ply");
  Mesh withn = a;
  ComputeVertexNormals(&withn);
  WritePly(d / "b.ply", withn);
  const Mesh b = ReadPly(d / "b.ply");
  EXPECT_EQ(b.positions, a.positions);
  EXPECT_EQ(b.triangles, a.triangles);
  ASSERT_EQ(b.normals.size(), withn.normals.size());
  for (std::size_t v = 0; v < b.normals.size(); ++v)
    EXPECT_TRUE(b.normals[v].isApprox(withn.normals[v], 1e-6f)) << v;  // float32, exactly the +z of the plane
  ASSERT_EQ(b.albedo.size(), a.albedo.size());
  for (std::size_t v = 0; v < b.albedo.size(); ++v)
    EXPECT_TRUE(b.albedo[v].isApprox(a.albedo[v], 1e-6f)) << v;  // pure red, green, blue: exact in 8 bits
  EXPECT_THROW(ParsePly("PLY junk", "x.ply"), InputError);
  EXPECT_THROW(ParsePly(ascii.substr(0, ascii.size() - 8), "trunc.ply"), InputError);
  std::string bad_index = ascii;
  bad_index.replace(bad_index.rfind("3 0 1 2"), 7, "3 0 1 9");
  EXPECT_THROW(ParsePly(bad_index, "idx.ply"), InputError);
  EXPECT_THROW(ParsePly("ply\nformat binary_little_endian 1.0\nelement vertex 1000000000\nproperty float x\n"
                        "property float y\nproperty float z\nend_header\n",
                        "huge.ply"),
               InputError);
}

TEST(Ply, AnElementWithNoPropertiesTakesNoBytesWhateverItsCount) {
  // The 1 KB file that hung `estimate` (issue 23): an unused element declared with a huge
  // count and no properties was skipped one empty row at a time.
  const std::string ply =
      "ply\nformat ascii 1.0\nelement skipme 4000000000000000000\nelement vertex 3\nproperty float x\n"
      "property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  const Mesh m = ParsePly(ply, "empty-element.ply");
  EXPECT_EQ(m.positions.size(), 3u);
  ASSERT_EQ(m.triangles.size(), 1u);
  EXPECT_EQ(m.triangles[0], Eigen::Vector3i(0, 1, 2));
  // An element with properties is still held to the bytes the file has.
  std::string with_props = ply;
  with_props.replace(with_props.find("element vertex"), 0, "property uchar junk\n");
  EXPECT_NE(ErrorOf([&] { ParsePly(with_props, "junk.ply"); }).find("count exceeds file size"), std::string::npos);
}

/// A file's bytes written to a temporary file and read as an image: the error, or "".
std::string ImageError(const std::string& bytes, const std::string& file) {
  const fs::path p = TempDir("claims") / file;
  std::ofstream(p, std::ios::binary) << bytes;
  return ErrorOf([&] { ReadImageLinear(p); });
}

std::string Le32(std::int32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); }

TEST(Image, AHeaderClaimingTooManyPixelsIsRefusedBeforeDecoding) {
  // 10000 x 10000 = 100 Mpx: over kMaxImagePixels (64 Mpx), under OpenCV's own 2^30.
  std::string png("\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR\0\0\x27\x10\0\0\x27\x10\x08\x02\0\0\0\0\0\0\0", 33);
  EXPECT_NE(ImageError(png, "big.png").find("header claims 10000 x 10000 pixels"), std::string::npos)
      << ImageError(png, "big.png");
  EXPECT_NE(ImageError("PF\n10000 10000\n-1.0\n" + std::string(64, '\0'), "big.pfm").find("10000 x 10000"),
            std::string::npos);
  EXPECT_NE(ImageError("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 9000 +X 12000\n" + std::string(64, '\0'), "big.hdr")
                .find("12000 x 9000"),
            std::string::npos);
  // OpenEXR: the dataWindow attribute (box2i, inclusive) among others.
  std::string exr("\x76\x2f\x31\x01\x02\0\0\0", 8);
  exr += std::string("channels\0chlist\0", 16) + Le32(1) + std::string(1, '\0');
  exr += std::string("dataWindow\0box2i\0", 17) + Le32(16) + Le32(0) + Le32(0) + Le32(9999) + Le32(9999);
  exr += std::string(1, '\0') + std::string(64, '\0');
  EXPECT_NE(ImageError(exr, "big.exr").find("header claims 10000 x 10000 pixels"), std::string::npos)
      << ImageError(exr, "big.exr");
  // Under the limit but more than the file can hold: a PFM's floats are all there or it is
  // corrupt; a PNG cannot inflate 33 bytes into 4 Mpx.
  EXPECT_NE(ImageError("PF\n100 100\n-1.0\n" + std::string(64, '\0'), "short.pfm").find("more than its 80 bytes can hold"),
            std::string::npos);
  std::string png_4mpx = png;
  png_4mpx[18] = png_4mpx[22] = '\x07';
  png_4mpx[19] = png_4mpx[23] = '\xd0';  // 2000 x 2000
  EXPECT_NE(ImageError(png_4mpx, "bomb.png").find("2000 x 2000 pixels, more than its 33 bytes can hold"),
            std::string::npos) << ImageError(png_4mpx, "bomb.png");
  // OpenEXR allocates an attribute's declared size before reading it: 1 GB claimed in a
  // 100-byte file is refused first.
  std::string exr_bomb("\x76\x2f\x31\x01\x02\0\0\0", 8);
  exr_bomb += std::string("junk\0unknowntype\0", 17) + Le32(1000000000) + std::string(64, 'x');
  EXPECT_NE(ImageError(exr_bomb, "bomb.exr").find("attribute 'junk' claims 1000000000 bytes"), std::string::npos)
      << ImageError(exr_bomb, "bomb.exr");
  // A real image under the limit still decodes (the check reads headers, not guesses).
  const fs::path ok = TempDir("claims-ok") / "ok.png";
  ImageRGB img(4, 3);
  WritePngSrgb(ok, img);
  EXPECT_EQ(ReadImageLinear(ok).width, 4);
}

TEST(Ply, ShadedColoursRoundTripAndAreOptional) {
  Mesh m = UvSphere({0, 0, 0}, 1, {0.4f, 0.5f, 0.6f}, 6, 8);
  EXPECT_TRUE(ReadPlyBack(m).shaded.empty()) << "a mesh without colours seen reads back without them";
  for (std::size_t v = 0; v < m.positions.size(); ++v) m.shaded.push_back({0.1f * v, 2.5f, 1e-3f});  // > 1 allowed
  const Mesh b = ReadPlyBack(m);
  EXPECT_EQ(b.shaded, m.shaded) << "stored as float, exactly";
  EXPECT_EQ(b.positions, m.positions);
  // A reader of the scene-bundle format that ignores them still reads the albedo.
  EXPECT_NEAR(b.albedo[0].y(), 0.5f, 0.01f);
  Mesh appended = m;
  appended.Append(UvSphere({3, 0, 0}, 1, {0.4f, 0.5f, 0.6f}, 6, 8));
  EXPECT_TRUE(appended.shaded.empty()) << "half a mesh's colours seen are none";
  Mesh both = m;
  both.Append(m);
  ASSERT_EQ(both.shaded.size(), 2 * m.shaded.size());
  EXPECT_EQ(both.shaded.back(), m.shaded.back());
}

TEST(Bundle, ClippedPixelsRoundTripAsLowerBoundsNotUsed) {
  // A pixel the camera clipped (a keyframe's block that held one) is written in
  // clipped<k>.png, read back as clipped and not valid; a saturated pixel of the image itself
  // inside the mask is clipped too, one outside the mask is not.
  const fs::path d = TempDir("clipped") / "scene";
  SceneBundle b = SmallBundle();
  b.views[0].clipped.assign(b.views[0].valid.size(), 0);
  b.views[0].clipped[5] = 1;
  b.views[0].valid[5] = 0;
  b.views[0].valid[7] = 0;  // masked out
  b.views[0].image.data[3 * 7] = 2.0f;
  b.views[0].image.data[3 * 9 + 1] = 2.0f;
  b.views[0].saturation = 1.5;
  WriteSceneBundle(d, b);
  EXPECT_TRUE(fs::exists(d / "clipped0.png"));
  const SceneBundle r = LoadSceneBundle(d);
  const View& v = r.views[0];
  ASSERT_EQ(v.clipped.size(), v.valid.size());
  EXPECT_EQ(v.clipped[5], 1);
  EXPECT_EQ(v.valid[5], 0);
  EXPECT_EQ(v.clipped[7], 0) << "outside the mask";
  EXPECT_EQ(v.clipped[9], 1) << "saturated in the image";
  EXPECT_EQ(v.valid[9], 0);
  EXPECT_EQ(v.saturated, 1);
  int clipped = 0;
  for (std::uint8_t c : v.clipped) clipped += c;
  EXPECT_EQ(clipped, 2);
  // A bundle with none writes no file.
  SceneBundle none = SmallBundle();
  WriteSceneBundle(d, none);
  EXPECT_FALSE(fs::exists(d / "clipped0.png"));
  EXPECT_TRUE(LoadSceneBundle(d).views[0].clipped.empty());
}

TEST(Bundle, PixelsClippedOffTheMeshRoundTripApartFromTheClipped) {
  // A pixel clipped where the mesh is not (a bulb with no depth) is written in
  // clipped_off<k>.png and read back as that, not valid and not `clipped` (which the
  // estimator takes as a glowing surface of the mesh).
  const fs::path d = TempDir("clipped_off") / "scene";
  SceneBundle b = SmallBundle();
  b.views[0].clipped_off.assign(b.views[0].valid.size(), 0);
  b.views[0].clipped_off[4] = 1;
  b.views[0].valid[4] = 0;
  WriteSceneBundle(d, b);
  EXPECT_TRUE(fs::exists(d / "clipped_off0.png"));
  EXPECT_FALSE(fs::exists(d / "clipped0.png"));
  const View v = LoadSceneBundle(d).views[0];
  ASSERT_EQ(v.clipped_off.size(), v.valid.size());
  int off = 0;
  for (std::uint8_t c : v.clipped_off) off += c;
  EXPECT_EQ(off, 1);
  EXPECT_EQ(v.clipped_off[4], 1);
  EXPECT_EQ(v.valid[4], 0);
  EXPECT_TRUE(v.clipped.empty());
  // A mask of another size is one clear error naming the file.
  WriteSceneBundle(d, SmallBundle());
  std::string json = ReadTextFile(d / "scene.json");
  json.insert(json.find("\"image\""), "\"clipped_off\": \"../other.png\", ");
  WriteTextAtomically(d / "scene.json", json);
  WriteMask(d.parent_path() / "other.png", Mask{3, 2, std::vector<std::uint8_t>(6, 255)});
  EXPECT_NE(test::ErrorOf([&] { LoadSceneBundle(d); }).find("clipped_off mask size does not match"), std::string::npos);
}

TEST(Ply, EmittersLabelAndRadianceRoundTrip) {
  Mesh m = UvSphere({0, 0, 0}, 1, {0.4f, 0.5f, 0.6f}, 6, 8);
  for (std::size_t v = 0; v < m.positions.size(); ++v) {
    m.label.push_back(static_cast<int>(v % 3) - 1);
    m.emission.push_back({0.5f * v, 2.5f, 1e-3f});
  }
  const Mesh b = ReadPlyBack(m);
  EXPECT_EQ(b.label, m.label);
  EXPECT_EQ(b.emission, m.emission);
  EXPECT_TRUE(ReadPlyBack(UvSphere({0, 0, 0}, 1, {0.4f, 0.5f, 0.6f}, 6, 8)).label.empty());
}

TEST(Ply, ReadsTheRealFragment) {
  const fs::path ply = fs::path(LIGHTPROBE_SOURCE_DIR) / "assets" / "mesh" / "frag_115.ply";
  Mesh m = ReadPly(ply);
  EXPECT_EQ(m.positions.size(), 64365u);
  EXPECT_EQ(m.triangles.size(), 127229u);
  EXPECT_GE(SanitizeMesh(&m, ply.string()), 0);
}

TEST(AtomicWrite, FailedWriteLeavesTheOldFile) {
  const fs::path d = TempDir("atomic");
  WriteTextAtomically(d / "r.txt", "old");
  EXPECT_THROW(WriteAtomically(d / "r.txt", [](const fs::path&) { throw InputError("boom"); }), InputError);
  EXPECT_EQ(ReadTextFile(d / "r.txt"), "old");
  int leftovers = 0;
  for (const auto& e : fs::directory_iterator(d)) leftovers += e.path().filename() != "r.txt";
  EXPECT_EQ(leftovers, 0);
}

// A full disk says so. /dev/full fails every write with ENOSPC, as a full file system does:
// the message WriteFailure gives then (what the atomic writers of text and images append to
// "cannot write") is the OS's, "no space left on device".
TEST(AtomicWrite, AFullDiskSaysNoSpaceLeftOnDevice) {
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full on this system";
  errno = 0;
  std::ofstream full("/dev/full", std::ios::binary);
  full << std::string(1 << 16, 'x');
  full.flush();
  const int saved = errno;
  ASSERT_FALSE(full) << "a write to /dev/full succeeded";
  EXPECT_EQ(saved, ENOSPC) << "the stream's failed write leaves the OS's errno";
  EXPECT_EQ(WriteFailure(fs::temp_directory_path(), saved), "no space left on device");
  EXPECT_EQ(WriteFailure("/dev", saved), "no space left on device");
  EXPECT_EQ(WriteFailure(fs::temp_directory_path(), EACCES), "permission denied");
}

}  // namespace
}  // namespace lp
