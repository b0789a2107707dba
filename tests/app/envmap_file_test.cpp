// The environment map's orientation, absolutely: a light from a known world direction must
// land on the pixel of envmap.exr that docs/formats.md says. The pixel is computed here by
// hand from the documented convention (row y: polar angle (y+1/2)/H*pi from up; column x:
// azimuth (x+1/2)/W*2pi from frame_x towards frame_y = up x frame_x; frame_x is world x
// projected off up), not with EnvMap's own spherical functions, and the file is the one
// `lightprobe estimate` writes (WriteEstimateOutputs), read back from disk.
#include <cmath>
#include <filesystem>
#include <unistd.h>

#include <gtest/gtest.h>

#include "app/commands.h"
#include "common/image_io.h"

namespace lp {
namespace {
namespace fs = std::filesystem;
constexpr double kPi = 3.14159265358979323846;

/// Writes an estimate whose map lights only the cell of `towards`; returns envmap.exr.
ImageRGB WrittenMap(const Eigen::Vector3d& up, const Eigen::Vector3d& towards, int rings, int* cell) {
  EstimateResult r;
  r.env = EnvMap(rings, up);
  r.lighting.map.assign(3 * r.env.size(), 0.0);
  r.left_out.assign(r.env.size(), 0);
  *cell = r.env.Lookup(towards);
  for (int c = 0; c < 3; ++c) r.lighting.map[3 * *cell + c] = 1.0;
  ConvergenceRow row;
  row.wall_seconds = 1;
  row.round = 1;
  r.convergence.push_back(row);
  SceneBundle bundle;
  bundle.dir = fs::temp_directory_path();
  const fs::path out = fs::temp_directory_path() / ("lp_envmap_file_" + std::to_string(::getpid()));
  app::WriteEstimateOutputs(out.string(), bundle, EstimateOptions{}, r, 1.0);
  ImageRGB image = ReadImageLinear(out / "envmap.exr");
  fs::remove_all(out);
  return image;
}

/// The pixel (column, row) of world direction `d` by the documented convention.
void DocumentedPixel(const Eigen::Vector3d& d, const Eigen::Vector3d& up, const Eigen::Vector3d& frame_x, int w,
                     int h, int* x, int* y) {
  const Eigen::Vector3d frame_y = up.cross(frame_x);
  const double theta = std::acos(d.dot(up));
  double phi = std::atan2(d.dot(frame_y), d.dot(frame_x));
  if (phi < 0) phi += 2 * kPi;
  *x = static_cast<int>(std::floor(phi / (2 * kPi) * w));
  *y = static_cast<int>(std::floor(theta / kPi * h));
}

float Lum(const ImageRGB& im, int x, int y) { return im.at(x, y)[0] + im.at(x, y)[1] + im.at(x, y)[2]; }

struct Case {
  Eigen::Vector3d up, frame_x, towards;
};

TEST(EnvMapFile, ALightLandsOnThePixelTheFormatDocSays) {
  // Up +z: frame_x = world x, frame_y = world y. Up +y: frame_x = world x, frame_y =
  // y x x = -z. Directions chosen off every symmetry (a mirrored or turned map lands
  // elsewhere).
  const Case cases[] = {
      {Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitX(), Eigen::Vector3d(2, 1, 0.5)},
      {Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitX(), Eigen::Vector3d(-0.3, -1, -0.4)},
      {Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitX(), Eigen::Vector3d(0.4, 0.8, -1)},
  };
  for (const Case& c : cases) {
    int cell = -1;
    const ImageRGB map = WrittenMap(c.up, c.towards.normalized(), 41, &cell);
    ASSERT_EQ(map.width, 256);
    ASSERT_EQ(map.height, 128);
    // The lit cell's centre direction, a world vector; its pixel by hand.
    const Eigen::Vector3d d = EnvMap(41, c.up).direction(cell);
    EXPECT_GT(d.dot(c.towards.normalized()), std::cos(5 * kPi / 180)) << "the cell holds the light";
    int x = 0, y = 0;
    DocumentedPixel(d, c.up, c.frame_x, map.width, map.height, &x, &y);
    EXPECT_GT(Lum(map, x, y), 0.f) << "light " << c.towards.transpose() << ": pixel (" << x << ", " << y << ") dark";
    // Only around there: the mirrored azimuth, the flipped pole and the opposite
    // direction are dark.
    const int mx = map.width - 1 - x, fy = map.height - 1 - y, ox = (x + map.width / 2) % map.width;
    if (std::abs(mx - x) > 4) {
      EXPECT_EQ(Lum(map, mx, y), 0.f) << "mirrored azimuth lit";
    }
    if (std::abs(fy - y) > 4) {
      EXPECT_EQ(Lum(map, x, fy), 0.f) << "flipped pole lit";
    }
    EXPECT_EQ(Lum(map, ox, fy), 0.f) << "opposite direction lit";
    // The lit pixels' centroid is that pixel, within the cell's half-size (4.5 degrees
    // between rings: 3.2 rows; azimuth wider near the poles).
    double sx = 0, sy = 0, n = 0;
    for (int j = 0; j < map.height; ++j)
      for (int i = 0; i < map.width; ++i)
        if (Lum(map, i, j) > 0) {
          sx += i;
          sy += j;
          n += 1;
        }
    ASSERT_GT(n, 0);
    EXPECT_NEAR(sy / n, y + 0.5, 2.5);
    EXPECT_NEAR(sx / n, x + 0.5, 2.5 / std::max(0.2, std::sin(std::acos(d.dot(c.up)))));
  }
}

}  // namespace
}  // namespace lp
