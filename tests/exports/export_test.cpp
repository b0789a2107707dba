// The exports' conventions against values computed by hand (docs/formats.md, "Exports"):
// where a world direction lands in Blender's and glTF's frames and on the pixels of
// world.exr / environment.hdr; spherical harmonics against closed forms and against the path
// tracer; the glTF file's lights, cameras and buffers. Blender itself opens the exports in
// blender_export_test.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "common/atomic_file.h"
#include "common/error.h"
#include "common/image_io.h"
#include "estimation/envmap.h"
#include "estimation/path_tracer.h"
#include "exports/axes.h"
#include "exports/blender.h"
#include "exports/export_scene.h"
#include "exports/gltf.h"
#include "exports/sh.h"
#include "scene/ray_tracer.h"
#include "scene/scene_bundle.h"
#include "tests/test_util.h"

namespace lp {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;
constexpr double kPi = 3.14159265358979323846;

fs::path Scratch(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("lp_export_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

/// The brightest pixel of an image.
std::pair<int, int> Brightest(const ImageRGB& im) {
  std::pair<int, int> best{-1, -1};
  float top = -1;
  for (int y = 0; y < im.height; ++y)
    for (int x = 0; x < im.width; ++x)
      if (im.at(x, y)[0] > top) top = im.at(x, y)[0], best = {x, y};
  return best;
}

TEST(ExportAxes, UpZIsBlendersFrameAndGltfTakesXZMinusY) {
  const ExportAxes a(Eigen::Vector3d::UnitZ());
  EXPECT_TRUE(a.blender_from_world.isApprox(Eigen::Matrix3d::Identity(), 1e-12));
  EXPECT_TRUE((a.gltf_from_world * Eigen::Vector3d(1, 2, 3)).isApprox(Eigen::Vector3d(1, 3, -2), 1e-12));
}

TEST(ExportAxes, UpYIsTurnedOntoZByAQuarterTurnAboutX) {
  const ExportAxes a(Eigen::Vector3d(0, 2, 0));  // not normalized on purpose
  // The smallest rotation taking +Y to +Z turns about X: X stays, Z goes to -Y.
  EXPECT_TRUE((a.blender_from_world * Eigen::Vector3d::UnitY()).isApprox(Eigen::Vector3d::UnitZ(), 1e-12));
  EXPECT_TRUE((a.blender_from_world * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitX(), 1e-12));
  EXPECT_TRUE((a.blender_from_world * Eigen::Vector3d::UnitZ()).isApprox(-Eigen::Vector3d::UnitY(), 1e-12));
  EXPECT_NEAR(a.blender_from_world.determinant(), 1.0, 1e-12);
  // glTF's up is +Y: the bundle's up lands there.
  EXPECT_TRUE((a.gltf_from_world * Eigen::Vector3d::UnitY()).isApprox(Eigen::Vector3d::UnitY(), 1e-12));
}

TEST(ExportAxes, BlendersEquirectangularMappingByHand) {
  // Cycles: u = 0.5 - atan2(y, x) / 2pi from the left edge, t = acos(z) / pi from the top.
  auto ut = [](double x, double y, double z) { return BlenderEquirectUt(Eigen::Vector3d(x, y, z)); };
  EXPECT_TRUE(ut(1, 0, 0).isApprox(Eigen::Vector2d(0.5, 0.5), 1e-12));    // +X: the centre
  EXPECT_TRUE(ut(0, 1, 0).isApprox(Eigen::Vector2d(0.25, 0.5), 1e-12));   // +Y: a quarter from the left
  EXPECT_TRUE(ut(0, -1, 0).isApprox(Eigen::Vector2d(0.75, 0.5), 1e-12));  // -Y: three quarters
  EXPECT_NEAR(ut(0, 0, 1).y(), 0.0, 1e-12);                               // up: the top row
  EXPECT_NEAR(ut(1, 0, 1).y(), 0.25, 1e-12);                              // 45 degrees above the horizon
  for (double u : {0.1, 0.37, 0.8})
    for (double t : {0.2, 0.5, 0.9})
      EXPECT_TRUE(BlenderEquirectUt(BlenderEquirectDirection(u, t)).isApprox(Eigen::Vector2d(u, t), 1e-9));
}

TEST(ExportAxes, ThreeJsMapsTheGltfDirectionToTheSamePixel) {
  // three.js's equirectUv (glTF frame g): u = atan(g.z, g.x) / 2pi + 0.5, v = asin(g.y) / pi + 0.5
  // from the bottom; environment.hdr is world.exr's picture, so these must agree.
  const Eigen::Matrix3d G = ExportAxes::GltfFromBlender();
  for (const Eigen::Vector3d& b : {Eigen::Vector3d(0.3, -0.8, 0.2), Eigen::Vector3d(-0.6, 0.1, -0.5),
                                   Eigen::Vector3d(0.1, 0.9, 0.7)}) {
    const Eigen::Vector3d g = G * b.normalized();
    const double u = std::atan2(g.z(), g.x()) / (2 * kPi) + 0.5, v = std::asin(g.y()) / kPi + 0.5;
    const Eigen::Vector2d blender = BlenderEquirectUt(b);
    EXPECT_NEAR(blender.x(), u, 1e-12);
    EXPECT_NEAR(1 - blender.y(), v, 1e-12);
  }
}

TEST(ExportAxes, AWorldDirectionLandsOnThePixelTheDocsSay) {
  // envmap.exr (EnvMap convention, up +Z, 64 x 32): pixel (5, 10) is azimuth 5.5/64 x 360 =
  // 30.9 deg from +X towards +Y, 10.5/32 x 180 = 59.1 deg from up. In world.exr (Blender):
  // column 64 x (0.5 - 30.9/360) - 0.5 = 26, row 10. Pixel (40, 3): column 64 x (0.5 -
  // 225.0/360) - 0.5 + 64 = 55, row 3.
  for (const auto& [src, dst] : {std::pair{std::pair{5, 10}, std::pair{26, 10}}, std::pair{std::pair{40, 3}, std::pair{55, 3}}}) {
    ImageRGB map(64, 32);
    map.at(src.first, src.second)[0] = 1;
    EXPECT_EQ(Brightest(BlenderWorldImage(map, Eigen::Vector3d::UnitZ(), 32)), dst);
  }
  // A bundle with up +Y: its up is the top row; world +X (azimuth 0 for up +Y) is the centre
  // column; world -Z (frame_y = up x frame_x = -Z, azimuth 90 deg) is a quarter from the left.
  const Eigen::Vector3d up = Eigen::Vector3d::UnitY();
  const EnvMap frame(2, up);
  auto lit_at = [&](const Eigen::Vector3d& w) {
    ImageRGB map(128, 64);
    double theta, phi;
    frame.ToSpherical(w, &theta, &phi);
    map.at(std::min(127, static_cast<int>(phi / (2 * kPi) * 128)), std::min(63, static_cast<int>(theta / kPi * 64)))[0] = 1;
    return Brightest(BlenderWorldImage(map, up, 64));
  };
  EXPECT_EQ(lit_at(Eigen::Vector3d(0.02, 1, 0.01)).second, 0);
  // World (1, 0.01, 0.01) is Blender (1, -0.01, 0.01): u = 0.5 + 0.0016 (column 64 of 128),
  // just above the horizon (row 31 of 64).
  EXPECT_EQ(lit_at(Eigen::Vector3d(1, 0.01, 0.01)), (std::pair{64, 31}));
  // World (0.01, 0.01, -1) is Blender (0.01, 1, 0.01): u = 0.5 - atan2(1, 0.01) / 2pi = 0.2516,
  // column 32.2.
  EXPECT_EQ(lit_at(Eigen::Vector3d(0.01, 0.01, -1)), (std::pair{32, 31}));
}

TEST(BlenderExport, AKeyframeCameraByHand) {
  // 80 x 60, fx = fy = 100, principal point 4 px right of and 2 px below the centre (39.5, 29.5).
  Camera c;
  c.width = 80, c.height = 60, c.fx = c.fy = 100, c.cx = 43.5, c.cy = 31.5;
  c.world_from_camera.block<3, 1>(0, 3) = Eigen::Vector3d(1, 2, 3);
  const BlenderCamera b = ToBlenderCamera(c, Eigen::Matrix3d::Identity());
  EXPECT_NEAR(b.lens_mm, 100.0 * 36 / 80, 1e-12);
  EXPECT_NEAR(b.shift_x, -4.0 / 80, 1e-12);  // the frame moves left when the principal point is right
  EXPECT_NEAR(b.shift_y, 2.0 / 80, 1e-12);
  // OpenCV's camera at the identity looks down +Z with y down; Blender's looks down its -Z, +Y up.
  EXPECT_TRUE((b.matrix_world.block<3, 3>(0, 0) * -Eigen::Vector3d::UnitZ()).isApprox(Eigen::Vector3d::UnitZ(), 1e-12));
  EXPECT_TRUE((b.matrix_world.block<3, 3>(0, 0) * Eigen::Vector3d::UnitY()).isApprox(-Eigen::Vector3d::UnitY(), 1e-12));
  const Eigen::Vector3d centre = b.matrix_world.block<3, 1>(0, 3);
  EXPECT_TRUE(centre.isApprox(Eigen::Vector3d(1, 2, 3), 1e-12));
}

// --- spherical harmonics ---

TEST(Sh, AConstantEnvironmentHasOnlyTheDcTerm) {
  const ImageRGB map(64, 32, 0.7f);
  const Sh9 L = ProjectMap(map, Eigen::Vector3d::UnitZ(), Eigen::Matrix3d::Identity());
  EXPECT_NEAR(L[0].x(), 0.7 * 2 * std::sqrt(kPi), 1e-6);  // 0.282095 x 4pi (0.7f: 1e-8 off)
  for (int i = 1; i < 9; ++i) EXPECT_NEAR(L[i].norm(), 0.0, 1e-9) << i;
  // Irradiance pi x 0.7 from every side.
  const Sh9 E = IrradianceFromRadiance(L);
  EXPECT_NEAR(EvaluateSh(E, Eigen::Vector3d(0.3, -0.4, 0.866).normalized()).x(), kPi * 0.7, 1e-6);
}

TEST(Sh, APolarCellsCoefficientsAreTheClosedForms) {
  // Only the top row lit (L = 2, a cap of half-angle a = pi/32 around up): the m != 0 terms
  // vanish and L00 = 2 x 0.282095 x 2pi(1 - cos a), L10 = 2 x 0.488603 x pi sin^2 a,
  // L20 = 2 x 0.315392 x 2pi cos a sin^2 a.
  ImageRGB map(64, 32);
  for (int x = 0; x < 64; ++x) map.at(x, 0)[0] = 2;
  const double a = kPi / 32;
  const Sh9 L = ProjectMap(map, Eigen::Vector3d::UnitZ(), Eigen::Matrix3d::Identity(), 8);
  EXPECT_NEAR(L[0].x(), 2 * 0.282094791773878 * 2 * kPi * (1 - std::cos(a)), 1e-9);
  EXPECT_NEAR(L[2].x(), 2 * 0.488602511902920 * kPi * std::sin(a) * std::sin(a), 1e-9);
  EXPECT_NEAR(L[6].x(), 2 * 0.315391565252520 * 2 * kPi * std::cos(a) * std::sin(a) * std::sin(a), 1e-9);
  for (int i : {1, 3, 4, 5, 7, 8}) EXPECT_NEAR(L[i].x(), 0.0, 1e-9) << i;
}

TEST(Sh, ASmallCellIsItsRadianceTimesSolidAngleTimesTheBasis) {
  ImageRGB map(256, 128);
  const int x = 40, y = 50;
  map.at(x, y)[1] = 3;
  const EnvMap frame(2, Eigen::Vector3d::UnitZ());
  const double t0 = y * kPi / 128, t1 = (y + 1) * kPi / 128, omega = (std::cos(t0) - std::cos(t1)) * 2 * kPi / 256;
  const Eigen::Vector3d d = frame.FromSpherical((y + 0.5) * kPi / 128, (x + 0.5) * 2 * kPi / 256);
  const auto Y = ShBasis(d);
  const Sh9 L = ProjectMap(map, Eigen::Vector3d::UnitZ(), Eigen::Matrix3d::Identity());
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(L[i].y(), 3 * omega * Y[i], 2e-3 * 3 * omega) << i;
}

TEST(Sh, AGlowingRectanglesCoefficientsAreItsSolidAngleAndIrradianceInClosedForm) {
  // A 0.8 x 0.5 m rectangle 1.2 m above the origin, facing it, radiance (2, 1, 0.5): its
  // L_00 is Y_00 L Omega with Omega = 4 arcsin(ab / sqrt((a^2 + d^2)(b^2 + d^2))) (a, b the
  // half-sides), its L_1,0 is Y_1 times the irradiance at the origin facing it, 4 pi L F with
  // F the corner form factor of each quarter (Howell's B-3). Seen from behind it adds nothing.
  const double a = 0.4, b = 0.25, d = 1.2;
  Mesh quad;
  quad.positions = {{-0.4f, -0.25f, 1.2f}, {0.4f, -0.25f, 1.2f}, {0.4f, 0.25f, 1.2f}, {-0.4f, 0.25f, 1.2f}};
  quad.albedo.assign(4, Eigen::Vector3f::Zero());
  quad.triangles = {{0, 1, 2}, {0, 2, 3}};
  EmitterLight e;
  e.shape = MakeEmitterShape(quad, {0, 1}, {-Eigen::Vector3f::UnitZ(), -Eigen::Vector3f::UnitZ()});
  e.radiance = {2, 1, 0.5};
  Sh9 sh;
  sh.fill(Eigen::Vector3d::Zero());
  AddEmitter(e, Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity(), &sh);
  const double omega = 4 * std::asin(a * b / std::sqrt((a * a + d * d) * (b * b + d * d)));
  const auto corner = [](double X, double Y) {
    const double p = std::sqrt(1 + X * X), q = std::sqrt(1 + Y * Y);
    return (X / p * std::atan(Y / p) + Y / q * std::atan(X / q)) / (2 * M_PI);
  };
  const double irradiance = 4 * M_PI * corner(a / d, b / d);  // per unit radiance
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(sh[0][c], 0.282094791773878 * e.radiance[c] * omega, 1e-6 * sh[0][c]) << c;  // (corners as floats)
    EXPECT_NEAR(sh[2][c], 0.488602511902920 * e.radiance[c] * irradiance, 5e-3 * 0.4886 * e.radiance[c] * irradiance) << c;
    EXPECT_NEAR(sh[1][c], 0.0, 1e-9) << "symmetric about the axis";
  }
  Sh9 behind;
  behind.fill(Eigen::Vector3d::Zero());
  AddEmitter(e, Eigen::Vector3d(0, 0, 2.4), Eigen::Matrix3d::Identity(), &behind);
  EXPECT_EQ(behind[0], Eigen::Vector3d::Zero());
}

TEST(Sh, TheBasisIsTheRealOrthonormalOneInThreeJsOrder) {
  // Each of the nine functions against its closed form (constants from their definitions,
  // not the code's decimals), in three.js's SphericalHarmonics3 order, at a generic direction.
  const Eigen::Vector3d d = Eigen::Vector3d(0.3, -0.5, 0.8).normalized();
  const double x = d.x(), y = d.y(), z = d.z();
  const double c0 = 0.5 / std::sqrt(kPi), c1 = std::sqrt(3 / (4 * kPi)), c2 = 0.5 * std::sqrt(15 / kPi),
               c20 = 0.25 * std::sqrt(5 / kPi), c22 = 0.25 * std::sqrt(15 / kPi);
  const double expected[9] = {c0, c1 * y, c1 * z, c1 * x, c2 * x * y, c2 * y * z, c20 * (3 * z * z - 1), c2 * x * z,
                              c22 * (x * x - y * y)};
  const auto Y = ShBasis(d);
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(Y[i], expected[i], 1e-12) << i;
  // Orthonormal over the sphere: the integral of Y_i Y_j by the midpoint rule on a 400 x 800
  // grid in (theta, phi) is the identity to 1e-4.
  double gram[9][9] = {};
  const int nt = 400, np = 800;
  for (int it = 0; it < nt; ++it)
    for (int ip = 0; ip < np; ++ip) {
      const double t = (it + 0.5) * kPi / nt, ph = (ip + 0.5) * 2 * kPi / np;
      const double w = std::sin(t) * (kPi / nt) * (2 * kPi / np);
      const auto B = ShBasis(Eigen::Vector3d(std::sin(t) * std::cos(ph), std::sin(t) * std::sin(ph), std::cos(t)));
      for (int i = 0; i < 9; ++i)
        for (int j = 0; j < 9; ++j) gram[i][j] += w * B[i] * B[j];
    }
  for (int i = 0; i < 9; ++i)
    for (int j = 0; j < 9; ++j) EXPECT_NEAR(gram[i][j], i == j ? 1.0 : 0.0, 1e-4) << i << "," << j;
}

TEST(Sh, ADirectionalLightsOrderTwoIrradianceIsOffBySixPercentAtItsPeak) {
  // A delta of irradiance E along d: L_i = E Y_i(d). The order-2 irradiance facing it is
  // E (1/4 + 1/2 + 5/16) = 1.0625 E (exact: E), and facing away 0.0625 E (exact: 0): the
  // truncation error a sun leaves in SH, stated in docs/formats.md and lighting.json.
  DirectionalLight sun;
  sun.direction = Eigen::Vector3d(0.2, -0.5, 0.8).normalized(), sun.irradiance = {2, 2, 2};
  Sh9 L;
  L.fill(Eigen::Vector3d::Zero());
  AddDirectional(sun, Eigen::Matrix3d::Identity(), &L);
  const auto Y = ShBasis(sun.direction);
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(L[i].x(), 2 * Y[i], 1e-12);
  const Sh9 E = IrradianceFromRadiance(L);
  EXPECT_NEAR(EvaluateSh(E, sun.direction).x(), 2 * 1.0625, 1e-9);
  EXPECT_NEAR(EvaluateSh(E, -sun.direction).x(), 2 * 0.0625, 1e-9);
}

/// An equirectangular sky (EnvMap convention around +Z) of order 2 in the direction:
/// L(w) = 0.2 + 0.3 (w.s) + 0.25 (w.s)^2 along a tilted axis s.
ImageRGB SmoothSky(int height) {
  const EnvMap frame(2, Eigen::Vector3d::UnitZ());
  const Eigen::Vector3d s = Eigen::Vector3d(0.5, 0.2, 0.8).normalized();
  ImageRGB map(2 * height, height);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < 2 * height; ++x) {
      const double c = frame.FromSpherical((y + 0.5) * kPi / height, (x + 0.5) * kPi / height).dot(s);
      const float v = static_cast<float>(0.2 + 0.3 * c + 0.25 * c * c);
      map.at(x, y)[0] = v, map.at(x, y)[1] = 0.9f * v, map.at(x, y)[2] = 0.8f * v;
    }
  return map;
}

TEST(Sh, APlanesIrradianceFromTheCoefficientsMatchesThePathTracerUnderASmoothSky) {
  // A large floor (albedo 0.6, normal +Z) seen from above under the sky: the path tracer's
  // pixels are 0.6 / pi x E(+Z); the order-2 irradiance is exact for a sky of order 2.
  const ImageRGB sky = SmoothSky(128);
  const Sh9 E = IrradianceFromRadiance(ProjectMap(sky, Eigen::Vector3d::UnitZ(), Eigen::Matrix3d::Identity()));
  const double from_sh = 0.6 / kPi * EvaluateSh(E, Eigen::Vector3d::UnitZ()).x();
  const Mesh floor = test::Plane(200, 0.6);
  const RayTracer tracer(floor);
  const EnvMap env(61, Eigen::Vector3d::UnitZ());
  const std::vector<double> lambda = env.FromEquirect(sky);
  const View view = test::BlankView(test::LookAt({0, 0, 2}, {0.3, 0.2, 0}, 40, 30, 50));
  TracerOptions t;
  t.spp = 256, t.bounces = 1;
  const ImageRGB im = RenderEnvironment(tracer, env, {view}, lambda, CellSampler(env, lambda, {}, 0.2), t, true)[0];
  double mean = 0;
  for (std::size_t p = 0; p < im.pixels(); ++p) mean += im.data[3 * p];
  mean /= im.pixels();
  std::printf("floor radiance: path tracer %.5f, order-2 SH %.5f (%.2f %%)\n", mean, from_sh, 100 * (from_sh / mean - 1));
  EXPECT_NEAR(from_sh / mean, 1.0, 0.01);
  // And against the map's own quadrature (no tracer, no cells): the SH are exact here.
  EXPECT_NEAR(EvaluateSh(E, Eigen::Vector3d::UnitZ()).x(),
              MapIrradiance(sky, Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ()).x(), 2e-4);
}

ExportScene SmallScene() {
  ExportScene s;
  s.mesh = test::Plane(2, 0.5);
  if (s.mesh.normals.size() != s.mesh.positions.size()) ComputeVertexNormals(&s.mesh);
  s.cameras.push_back(test::LookAt({0, -2, 1.5}, {0, 0, 0}, 80, 60, 60));
  return s;
}

json ReadJson(const fs::path& p) { return json::parse(ReadTextFile(p)); }

TEST(ShExport, TheMainLightIsTheSunAndTheCoefficientsLeaveItOut) {
  ExportScene s = SmallScene();
  s.environment = SmoothSky(32);
  DirectionalLight sun;
  sun.direction = Eigen::Vector3d(0.3, 0.4, 0.866).normalized(), sun.irradiance = {3, 2.7, 2.4};
  s.lights.push_back(sun);
  const fs::path dir = Scratch("sh_sun");
  WriteExport(s, ExportFormat::kSh, dir);
  const json j = ReadJson(dir / "lighting.json");
  EXPECT_EQ(j["main_light"]["source"], "directional_light");
  EXPECT_NEAR(j["main_light"]["intensity"].get<double>(), 3.0, 1e-12);
  EXPECT_NEAR(j["main_light"]["color"][1].get<double>(), 0.9, 1e-12);
  const Sh9 sky = ProjectMap(s.environment, s.up, Eigen::Matrix3d::Identity());
  EXPECT_NEAR(j["sh9_radiance"][2][0].get<double>(), sky[2].x(), 1e-9);  // the map alone
  // The smooth sky alone is of order 2: the stated truncation error is small.
  EXPECT_LT(j["sh9_irradiance_error"]["max"].get<double>(), 0.01);
  // In the Y-up frame the up-down coefficient L10 of the bundle becomes L1-1 (glTF's y).
  EXPECT_NEAR(j["y_up"]["sh9_radiance"][1][0].get<double>(), sky[2].x(), 1e-6);
  fs::remove_all(dir);
}

TEST(ShExport, TheYUpCoefficientsAreTheSameFunctionTurned) {
  // A sky and one bright off-axis patch (every coefficient non-zero, no symmetry to hide a
  // mirror): the Y-up set evaluated at glTF's (x, z, -y) of a world direction gives what the
  // bundle's set gives at the direction itself, radiance and irradiance alike.
  ExportScene s = SmallScene();
  s.environment = SmoothSky(32);
  for (int y = 6; y < 9; ++y)
    for (int x = 11; x < 15; ++x) s.environment.at(x, y)[0] = 8, s.environment.at(x, y)[1] = 5;
  const fs::path dir = Scratch("sh_yup");
  WriteExport(s, ExportFormat::kSh, dir);
  const json j = ReadJson(dir / "lighting.json");
  const auto read = [](const json& a) {
    Sh9 sh;
    for (int i = 0; i < 9; ++i) sh[i] = Eigen::Vector3d(a[i][0].get<double>(), a[i][1].get<double>(), a[i][2].get<double>());
    return sh;
  };
  for (const char* key : {"sh9_radiance", "sh9_irradiance"}) {
    const Sh9 world = read(j[key]), yup = read(j["y_up"][key]);
    EXPECT_GT(std::abs(world[4].x()) + std::abs(world[8].x()), 1e-3) << "the patch reaches the second band";
    for (int k = 0; k < 20; ++k) {
      const double t = 0.3 + 0.13 * k, p = 2.1 * k;
      const Eigen::Vector3d d(std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t));
      const Eigen::Vector3d a = EvaluateSh(world, d), b = EvaluateSh(yup, Eigen::Vector3d(d.x(), d.z(), -d.y()));
      EXPECT_NEAR((a - b).norm(), 0, 1e-6 * (1 + a.norm())) << key << " " << k;
    }
  }
  fs::remove_all(dir);
}

TEST(ShExport, WithTheSunInTheCoefficientsTheOrderTwoErrorIsStated) {
  // A map with a sun-like bright patch (no directional light): the main light comes from the
  // map, the patch is in the SH, and the stated error is what order 2 leaves (several %).
  ExportScene s = SmallScene();
  s.environment = SmoothSky(32);
  for (int y = 6; y < 8; ++y)
    for (int x = 20; x < 22; ++x) s.environment.at(x, y)[0] = s.environment.at(x, y)[1] = s.environment.at(x, y)[2] = 400;
  const fs::path dir = Scratch("sh_map");
  WriteExport(s, ExportFormat::kSh, dir);
  const json j = ReadJson(dir / "lighting.json");
  EXPECT_EQ(j["main_light"]["source"], "map");
  const EnvMap frame(2, Eigen::Vector3d::UnitZ());
  const Eigen::Vector3d patch = frame.FromSpherical(7.0 * kPi / 32, 21.0 * kPi / 32);
  const Eigen::Vector3d d(j["main_light"]["direction"][0], j["main_light"]["direction"][1], j["main_light"]["direction"][2]);
  EXPECT_GT(d.dot(patch), std::cos(3 * kPi / 180));
  const double worst = j["sh9_irradiance_error"]["max"];
  std::printf("order-2 irradiance error with a sun in the map: rms %.3f, max %.3f\n",
              j["sh9_irradiance_error"]["rms"].get<double>(), worst);
  EXPECT_GT(worst, 0.03);
  EXPECT_LT(worst, 0.2);
  fs::remove_all(dir);
}

TEST(ShExport, EachLightCarriesItsUncertaintyInBothFrames) {
  // lighting.json gives each light lights.json's covariance and sigma, the covariance also
  // in the y-up frame (G C G^T: a variance along world z is one along y-up's y), and null
  // where unknown; with no uncertainty the keys are absent.
  ExportScene s = SmallScene();
  s.lights.push_back(PointLight{{0.5, 0.2, 1.5}, {2, 2, 2}, 0});
  s.lights.push_back(DirectionalLight{Eigen::Vector3d(0, 0.6, 0.8), {1, 1, 1}, 0});
  LightUncertainty lamp, sun;
  lamp.shape_covariance = Eigen::Vector3d(1e-4, 4e-4, 9e-4).asDiagonal();
  lamp.scale_sigma = {0.1, 0.2, 0.3};
  sun.shape_covariance.setConstant(INFINITY);
  sun.scale_sigma = {0.01, 0.01, 0.01};
  s.uncertainty = {lamp, sun};
  const fs::path dir = Scratch("sh_uncertainty");
  WriteExport(s, ExportFormat::kSh, dir);
  const json j = ReadJson(dir / "lighting.json");
  const json& l = j["point_lights"].at(0);
  EXPECT_DOUBLE_EQ(l["position_covariance"][2][2].get<double>(), 9e-4);
  EXPECT_DOUBLE_EQ(l["position_covariance_y_up"][1][1].get<double>(), 9e-4);  // world z is y-up's y
  EXPECT_DOUBLE_EQ(l["position_covariance_y_up"][2][2].get<double>(), 4e-4);  // world y is y-up's -z
  EXPECT_DOUBLE_EQ(l["intensity_sigma"][2].get<double>(), 0.3);
  const json& d = j["directional_lights"].at(0);
  EXPECT_TRUE(d["direction_covariance"][0][0].is_null());
  EXPECT_DOUBLE_EQ(d["irradiance_sigma"][0].get<double>(), 0.01);
  s.uncertainty.clear();
  WriteExport(s, ExportFormat::kSh, dir);
  EXPECT_FALSE(ReadJson(dir / "lighting.json")["point_lights"].at(0).contains("position_covariance"));
  fs::remove_all(dir);
}

TEST(GltfExport, LightsCamerasAndBuffersByHand) {
  ExportScene s = SmallScene();
  PointLight lamp;
  lamp.position = {1, 2, 3}, lamp.intensity = {2, 1, 0.5}, lamp.radius = 0.1;
  s.lights.push_back(lamp);
  DirectionalLight sun;
  sun.direction = Eigen::Vector3d(0, 0.6, 0.8), sun.irradiance = {1, 1, 4};
  s.lights.push_back(sun);
  const fs::path dir = Scratch("gltf");
  WriteExport(s, ExportFormat::kGltf, dir);
  const json j = ReadJson(dir / "scene.gltf");
  EXPECT_EQ(j["buffers"][0]["byteLength"].get<std::size_t>(), fs::file_size(dir / "scene.bin"));
  EXPECT_EQ(j["accessors"][0]["count"].get<std::size_t>(), s.mesh.positions.size());
  const json& lights = j["extensions"]["KHR_lights_punctual"]["lights"];
  ASSERT_EQ(lights.size(), 2u);
  EXPECT_NEAR(lights[0]["intensity"].get<double>(), 683 * 2.0, 1e-9);  // candela = 683 x W/sr
  EXPECT_NEAR(lights[0]["color"][2].get<double>(), 0.25, 1e-12);
  EXPECT_NEAR(lights[1]["intensity"].get<double>(), 683 * 4.0, 1e-9);  // lux = 683 x W/m^2
  json lamp_node, sun_node, camera_node;
  for (const json& n : j["nodes"]) {
    if (n.value("name", "") == "point_light_0") lamp_node = n;
    if (n.value("name", "") == "sun_0") sun_node = n;
    if (n.value("name", "") == "keyframe_0") camera_node = n;
  }
  // (1, 2, 3) with up +Z is glTF (1, 3, -2).
  EXPECT_NEAR(lamp_node["translation"][1].get<double>(), 3.0, 1e-12);
  EXPECT_NEAR(lamp_node["translation"][2].get<double>(), -2.0, 1e-12);
  // The sun's node turns its -Z (where it shines) onto -direction: glTF -(0, 0.8, -0.6).
  const Eigen::Quaterniond q(sun_node["rotation"][3], sun_node["rotation"][0], sun_node["rotation"][1],
                             sun_node["rotation"][2]);
  EXPECT_TRUE((q * -Eigen::Vector3d::UnitZ()).isApprox(Eigen::Vector3d(0, -0.8, 0.6), 1e-9));
  // The camera 2 m behind and 1.5 m above (bundle) is at glTF (0, 1.5, 2), looking along its -Z.
  const json& m = camera_node["matrix"];
  EXPECT_NEAR(m[12].get<double>(), 0.0, 1e-9);
  EXPECT_NEAR(m[13].get<double>(), 1.5, 1e-9);
  EXPECT_NEAR(m[14].get<double>(), 2.0, 1e-9);
  EXPECT_NEAR(j["cameras"][0]["perspective"]["aspectRatio"].get<double>(), 80.0 / 60, 1e-9);
  fs::remove_all(dir);
}

// A pane over a hole (EmitterLight::in_a_hole: on no triangle of the mesh) is a primitive of
// its own: its two triangles wound to face the side it glows on (a pane at x = 1 glowing
// towards -x; glTF's x is the bundle's with up +Z), emissive at its radiance, the mesh's
// primitive not.
TEST(GltfExport, APaneOverAHoleIsAGlowingPrimitiveOfItsOwn) {
  ExportScene s = SmallScene();
  Mesh quad;
  quad.positions = {{1, -0.4f, 0.5f}, {1, 0.4f, 0.5f}, {1, 0.4f, 1.3f}, {1, -0.4f, 1.3f}};
  quad.triangles = {{0, 1, 2}, {0, 2, 3}};
  EmitterLight pane;
  pane.shape = MakeEmitterShape(quad, {0, 1}, {-Eigen::Vector3f::UnitX(), -Eigen::Vector3f::UnitX()});
  pane.radiance = {3, 2.7, 2.25};
  pane.in_a_hole = true;
  s.lights.push_back(pane);
  const fs::path dir = Scratch("gltf_pane");
  WriteExport(s, ExportFormat::kGltf, dir);
  const json j = ReadJson(dir / "scene.gltf");
  const json& primitives = j["meshes"][0]["primitives"];
  ASSERT_EQ(primitives.size(), 2u);  // the mesh (nothing of it glows) and the pane
  const json& material = j["materials"][primitives[1]["material"].get<int>()];
  EXPECT_NEAR(material["extras"]["radiance"][0].get<double>(), 3.0, 1e-12);
  EXPECT_NEAR(material["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"].get<double>(), 683 * 3.0,
              1e-9);
  EXPECT_FALSE(material["doubleSided"].get<bool>());
  EXPECT_EQ(j["accessors"][primitives[1]["attributes"]["POSITION"].get<int>()]["count"].get<int>(), 6);
  EXPECT_EQ(j["accessors"][primitives[1]["indices"].get<int>()]["count"].get<int>(), 6);
  EXPECT_FALSE(j["materials"][primitives[0]["material"].get<int>()].contains("emissiveFactor"));
  // Its faces wound to the side that emits: the first triangle's normal is -x (glTF's -x too).
  const json& bytes_view = j["bufferViews"][j["accessors"][primitives[1]["attributes"]["POSITION"].get<int>()]["bufferView"].get<int>()];
  std::ifstream bin(dir / "scene.bin", std::ios::binary);
  std::vector<float> p(9);
  bin.seekg(bytes_view.value("byteOffset", 0));
  bin.read(reinterpret_cast<char*>(p.data()), 9 * sizeof(float));
  const Eigen::Vector3f a(p[0], p[1], p[2]), b(p[3], p[4], p[5]), c(p[6], p[7], p[8]);
  EXPECT_LT((b - a).cross(c - a).x(), 0) << a.transpose() << " / " << b.transpose() << " / " << c.transpose();
  fs::remove_all(dir);
}

TEST(Export, TheRefinedAlbedoMeshReplacesTheBundles) {
  // ESTIMATE_DIR/albedo_mesh.ply (the de-lit mesh) when the estimate wrote one, else the bundle's.
  const fs::path dir = Scratch("refined");
  SceneBundle b;
  b.mesh = test::Plane(2, 0.5);
  b.views.push_back(test::BlankView(test::LookAt({0, -2, 1.5}, {0, 0, 0}, 8, 6, 60)));
  b.views[0].image = ImageRGB(8, 6, 0.1f);
  WriteSceneBundle(dir / "scene", b);
  fs::create_directories(dir / "estimate");
  WriteTextAtomically(dir / "estimate" / "lights.json", "{\"point_lights\": []}");
  EXPECT_NEAR(LoadExportScene(dir / "scene", dir / "estimate").mesh.albedo[0].x(), 0.5, 0.01);
  Mesh refined = b.mesh;
  for (auto& a : refined.albedo) a = Eigen::Vector3f(0.2f, 0.3f, 0.4f);
  WritePly(dir / "estimate" / "albedo_mesh.ply", refined);
  const ExportScene s = LoadExportScene(dir / "scene", dir / "estimate");
  EXPECT_NEAR(s.mesh.albedo[0].y(), 0.3, 0.01);
  EXPECT_NE(s.mesh_source.find("albedo_mesh.ply"), std::string::npos);
  EXPECT_EQ(s.cameras.size(), 1u);
  EXPECT_EQ(s.environment.height, 0) << "no map in lights.json: none exported";
  fs::remove_all(dir);
}

TEST(Export, AMissingLightsFileIsAClearError) {
  const fs::path dir = Scratch("missing");
  try {
    LoadExportScene(dir / "scene", dir);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("lights.json"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ParseExportFormat("obj"), InputError);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace lp
