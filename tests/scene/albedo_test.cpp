// FlattenAlbedo and DelightAlbedo: shading baked into the fused colour is flattened per segment of one
// chromaticity; different materials stay apart.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "scene/albedo.h"

namespace lp {
namespace {

/// A strip of n x 2 vertices along x, colour `rgb` scaled by shading(x).
Mesh Strip(int n, float x0, const Eigen::Vector3f& rgb, float shade0, float shade1) {
  Mesh m;
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < 2; ++k) {
      m.positions.push_back({x0 + 0.01f * i, 0.01f * k, 0});
      const float s = shade0 + (shade1 - shade0) * i / (n - 1);
      m.albedo.push_back(rgb * s);
    }
  for (int i = 0; i + 1 < n; ++i) {
    const int a = 2 * i, b = 2 * i + 1, c = 2 * i + 2, d = 2 * i + 3;
    m.triangles.push_back({a, c, b});
    m.triangles.push_back({b, c, d});
  }
  return m;
}

TEST(FlattenAlbedo, ShadingInsideAMaterialIsFlattenedMaterialsStayApart) {
  // Beige fading from full light to a third (smoothly: 1 % per vertex), then a blue strip
  // joined to it (the same vertices' neighbours across the seam).
  Mesh beige = Strip(300, 0, {0.6f, 0.5f, 0.35f}, 1.0f, 0.33f);
  Mesh blue = Strip(300, 3.0f, {0.1f, 0.2f, 0.6f}, 0.5f, 0.9f);
  const int seam_a = 2 * 299, seam_b = 2 * 299 + 1;
  beige.Append(blue);
  const int offset = 600;
  beige.triangles.push_back({seam_a, offset, seam_b});  // connect the strips
  beige.triangles.push_back({seam_b, offset, offset + 1});
  AlbedoOptions o;
  o.min_segment = 50;
  ASSERT_EQ(FlattenAlbedo(&beige, o), 2);
  // Each strip is one colour: the mean of its shaded colours.
  for (int v = 1; v < 600; ++v) EXPECT_TRUE(beige.albedo[v].isApprox(beige.albedo[0], 1e-5f)) << v;
  for (int v = 601; v < 1200; ++v) EXPECT_TRUE(beige.albedo[v].isApprox(beige.albedo[600], 1e-5f)) << v;
  const float mean_shade = (1.0f + 0.33f) / 2;
  EXPECT_NEAR(beige.albedo[0].x(), 0.6f * mean_shade, 1e-3f);
  EXPECT_NEAR(beige.albedo[600].z(), 0.6f * 0.7f, 1e-3f);
  // Its chromaticity is kept.
  EXPECT_NEAR(beige.albedo[0].x() / beige.albedo[0].z(), 0.6f / 0.35f, 1e-3f);
}

TEST(FlattenAlbedo, AnAbruptBrightnessStepSplitsAndSmallSegmentsKeepTheirColour) {
  Mesh dark = Strip(100, 0, Eigen::Vector3f::Constant(0.2f), 1, 1);
  Mesh light = Strip(100, 1.0f, Eigen::Vector3f::Constant(0.8f), 1, 1);
  Mesh tiny = Strip(5, 5.0f, Eigen::Vector3f(0.9f, 0.1f, 0.1f), 1, 0.5f);
  dark.Append(light);
  dark.triangles.push_back({198, 200, 199});  // a grey-level step of 4x across this edge
  dark.Append(tiny);
  const std::vector<Eigen::Vector3f> before = dark.albedo;
  AlbedoOptions o;
  o.min_segment = 50;
  EXPECT_EQ(FlattenAlbedo(&dark, o), 2);
  EXPECT_NEAR(dark.albedo[0].x(), 0.2f, 1e-5f);
  EXPECT_NEAR(dark.albedo[399].x(), 0.8f, 1e-5f);
  for (int v = 400; v < 410; ++v) EXPECT_EQ(dark.albedo[v], before[v]) << "segments under min_segment are kept";
  // Off: nothing changes.
  Mesh off = Strip(100, 0, {0.6f, 0.5f, 0.35f}, 1.0f, 0.5f);
  const std::vector<Eigen::Vector3f> original = off.albedo;
  o.segment = false;
  EXPECT_EQ(FlattenAlbedo(&off, o), 0);
  EXPECT_EQ(off.albedo, original);
}

TEST(FlattenAlbedo, AlikeSegmentsApartAreOneMaterialTouchingOnesStayApart) {
  // Three grey strips that do not touch: 0.5 and 0.4 (a checker's squares of one paint,
  // one darker by the light left in it: log luminances 0.22 apart) and 0.1 (another paint,
  // 1.4 apart); a fourth, 0.4, touches the first across a step.
  Mesh m = Strip(100, 0, Eigen::Vector3f::Constant(0.5f), 1, 1);
  m.Append(Strip(60, 2.0f, Eigen::Vector3f::Constant(0.4f), 1, 1));
  m.Append(Strip(80, 4.0f, Eigen::Vector3f::Constant(0.1f), 1, 1));
  m.Append(Strip(70, 1.0f, Eigen::Vector3f::Constant(0.4f), 1, 1));  // vertices 480..619
  m.triangles.push_back({198, 480, 199});
  const Mesh seen = m;
  AlbedoOptions o;
  o.min_segment = 50;
  o.max_log_spread = o.max_log_step;
  EXPECT_EQ(FlattenAlbedo(&m, o), 4) << "not joined apart: four segments";
  m = seen;
  o.max_apart_log_spread = 0.5f;
  EXPECT_EQ(FlattenAlbedo(&m, o), 3);
  const float joined = (200 * 0.5f + 120 * 0.4f) / 320;  // the mean over both, by vertices
  EXPECT_NEAR(m.albedo[0].x(), joined, 1e-5f);
  EXPECT_NEAR(m.albedo[200].x(), joined, 1e-5f);
  EXPECT_NEAR(m.albedo[320].x(), 0.1f, 1e-5f) << "another paint stays apart";
  EXPECT_NEAR(m.albedo[480].x(), 0.4f, 1e-5f) << "a step across an edge is a material's: kept apart";
}

/// A floor and a wall of one chromaticity, albedos 1.38 apart (the demo's floor and grey
/// wall), lit so that the colour seen is continuous across their seam: the floor's
/// irradiance falls from 1 to 0.725 towards the seam, the wall's from 1 at the seam to 0.6.
struct FloorAndWall {
  Mesh mesh;
  std::vector<float> irradiance;
  static constexpr float kFloor = 0.6f, kRatio = 1.38f;
  FloorAndWall() {
    const Eigen::Vector3f tint(1.0f, 0.9f, 0.8f);
    mesh = Strip(300, 0, tint * kFloor, 1.0f, 0.725f);
    Mesh wall = Strip(300, 3.0f, tint * (kFloor / kRatio), 1.0f, 0.6f);
    const int seam_a = 2 * 299, seam_b = 2 * 299 + 1;
    mesh.Append(wall);
    mesh.triangles.push_back({seam_a, 600, seam_b});
    mesh.triangles.push_back({seam_b, 600, 601});
    mesh.shaded = mesh.albedo;  // Strip made albedo x shading: the colour seen
    for (int i = 0; i < 300; ++i)
      for (int k = 0; k < 2; ++k) irradiance.push_back(1.0f - 0.275f * i / 299);
    for (int i = 0; i < 300; ++i)
      for (int k = 0; k < 2; ++k) irradiance.push_back(1.0f - 0.4f * i / 299);
  }
};

TEST(DelightAlbedo, VerticesNoSegmentFlattensAreDelitByTheSmoothedIrradiance) {
  // Every vertex left to itself (segments under min_segment), the irradiance 20 % noisy per
  // vertex: each keeps its own de-lit colour, divided by the irradiance smoothed over the
  // surface, so its error is a fraction of the noise's (the speckle on the lit mesh).
  // Without normals nothing is smoothed (SmoothOverSurface needs them): the noise's own.
  const auto rms_error = [](bool normals) {
    FloorAndWall s;
    if (normals) s.mesh.normals.assign(s.mesh.positions.size(), Eigen::Vector3f::UnitZ());
    std::vector<float> noisy = s.irradiance;
    for (std::size_t v = 0; v < noisy.size(); ++v) noisy[v] *= 1 + 0.2f * (((v * 2654435761u) >> 7) % 1000 / 500.f - 1);
    AlbedoOptions d = DelitAlbedoOptions();
    d.min_segment = 100000;
    Mesh mesh = s.mesh;
    EXPECT_EQ(DelightAlbedo(&mesh, noisy, d, 1.0, 0.5), 0);
    std::vector<double> ratio;  // the de-lit albedo over the truth's: one scale for all
    for (std::size_t v = 0; v < noisy.size(); ++v) {
      const float truth = v < 600 ? FloorAndWall::kFloor : FloorAndWall::kFloor / FloorAndWall::kRatio;
      ratio.push_back(mesh.albedo[v].x() / truth);
    }
    std::vector<double> sorted = ratio;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    double e2 = 0;
    for (double r : ratio) e2 += std::pow(r / sorted[sorted.size() / 2] - 1, 2);
    return std::sqrt(e2 / ratio.size());
  };
  const double raw = rms_error(false), smoothed = rms_error(true);
  std::printf("de-lit albedo's error, every vertex its own: %.2f %% raw, %.2f %% smoothed\n", 100 * raw, 100 * smoothed);
  EXPECT_GT(raw, 0.08);
  EXPECT_LT(smoothed, raw / 2.5);
}

TEST(DelightAlbedo, TwoSurfacesOfOneChromaticityMergedByTheColourSeenAreSplitByTheirIrradiance) {
  FloorAndWall s;
  AlbedoOptions o;
  o.min_segment = 50;
  Mesh seen = s.mesh;
  ASSERT_EQ(FlattenAlbedo(&seen, o), 1) << "the colour seen is continuous: one segment";
  EXPECT_TRUE(seen.albedo[0].isApprox(seen.albedo[1199], 1e-5f));

  AlbedoOptions d = DelitAlbedoOptions();
  d.min_segment = 50;
  double before = 0;
  for (const auto& a : s.mesh.albedo) before += a.sum();
  ASSERT_EQ(DelightAlbedo(&s.mesh, s.irradiance, d), 2);
  const Eigen::Vector3f floor = s.mesh.albedo[0], wall = s.mesh.albedo[1199];
  for (int v = 0; v < 600; ++v) EXPECT_TRUE(s.mesh.albedo[v].isApprox(floor, 1e-5f)) << v;
  for (int v = 600; v < 1200; ++v) EXPECT_TRUE(s.mesh.albedo[v].isApprox(wall, 1e-5f)) << v;
  EXPECT_NEAR(floor.sum() / wall.sum(), FloorAndWall::kRatio, 0.005 * FloorAndWall::kRatio);
  EXPECT_NEAR(floor.x() / floor.z(), 1.0 / 0.8, 1e-3) << "chromaticity kept";
  double after = 0;
  for (const auto& a : s.mesh.albedo) after += a.sum();
  EXPECT_NEAR(after, before, 1e-4 * before) << "the mean albedo (the light's scale) is unchanged";
}

TEST(DelightAlbedo, AnAbsoluteScaleIsKeptAndClippedAtTheLargestAlbedo) {
  // The same de-lighting at scale 3: every albedo three times the scale-1 result, none
  // above kMaxAlbedo.
  FloorAndWall one, three;
  AlbedoOptions d = DelitAlbedoOptions();
  d.min_segment = 50;
  ASSERT_EQ(DelightAlbedo(&one.mesh, one.irradiance, d), 2);
  ASSERT_EQ(DelightAlbedo(&three.mesh, three.irradiance, d, 3.0), 2);
  for (int v : {0, 599, 600, 1199})
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(three.mesh.albedo[v][c], std::min(kMaxAlbedo, 3 * one.mesh.albedo[v][c]), 1e-5f) << v << "," << c;
}

TEST(DelightAlbedo, TheMedianRuleGivesTheDelitAlbedoThatMedian) {
  // De-lit, the floor is 0.6 x tint and the wall 0.6 / 1.38 x tint (as many vertices
  // each); with a median the albedo's median luminance is that, whatever the colours'
  // mean (the light's fall-off is in it), the floor / wall ratio kept.
  FloorAndWall s;
  AlbedoOptions d = DelitAlbedoOptions();
  d.min_segment = 50;
  ASSERT_EQ(DelightAlbedo(&s.mesh, s.irradiance, d, 1.0, 0.3), 2);
  EXPECT_NEAR(AlbedoScaleTo(s.mesh, 0.3), 1, 1e-5) << "its median luminance is 0.3";
  EXPECT_NEAR(s.mesh.albedo[0].sum() / s.mesh.albedo[1199].sum(), FloorAndWall::kRatio, 0.005 * FloorAndWall::kRatio);
  const float floor_lum = 0.2126f * s.mesh.albedo[0].x() + 0.7152f * s.mesh.albedo[0].y() + 0.0722f * s.mesh.albedo[0].z();
  EXPECT_NEAR(floor_lum, 0.3f, 1e-4f) << "the upper of the two halves is the median (nth_element at n/2)";
}

TEST(AlbedoScale, TheMedianIsTakenToTheGivenAlbedo) {
  // 101 vertices of luminance 0.01 .. 1.01 (grey): the median is the 51st, 0.51.
  Mesh m;
  for (int i = 1; i <= 101; ++i) m.albedo.push_back(Eigen::Vector3f::Constant(0.01f * i));
  std::reverse(m.albedo.begin(), m.albedo.end());  // (any order)
  EXPECT_NEAR(AlbedoScaleTo(m, 0.7), 0.7 / 0.51, 1e-5);
  EXPECT_EQ(AlbedoScaleTo(m, 0), 1) << "0: the colours' scale";
  ScaleAlbedo(&m, 2);
  EXPECT_FLOAT_EQ(m.albedo[100].x(), 0.02f);
  EXPECT_FLOAT_EQ(m.albedo[0].x(), kMaxAlbedo) << "clipped";
  Mesh black;
  black.albedo.assign(10, Eigen::Vector3f::Zero());
  EXPECT_EQ(AlbedoScaleTo(black, 0.7), 1) << "nothing to scale";
}

TEST(DelightAlbedo, NoisyIrradianceStillSplitsAndUnlitVerticesStayFinite) {
  FloorAndWall s;
  std::uint32_t state = 12345;
  for (float& e : s.irradiance) {  // 5 % multiplicative noise (an estimate's Monte Carlo)
    state = state * 1664525u + 1013904223u;
    e *= 1.0f + 0.1f * (static_cast<float>(state >> 8) / 16777216.0f - 0.5f);
  }
  AlbedoOptions d = DelitAlbedoOptions();
  d.min_segment = 50;
  Mesh m = s.mesh;
  ASSERT_EQ(DelightAlbedo(&m, s.irradiance, d), 2);
  EXPECT_NEAR(m.albedo[0].sum() / m.albedo[1199].sum(), FloorAndWall::kRatio, 0.03 * FloorAndWall::kRatio);

  // A second pass from the first's output keeps the scale of the colours seen, clipped
  // values and all: a dim patch (a tenth of the irradiance) de-lights past 0.95.
  {
    Mesh twice = s.mesh;
    std::vector<float> irradiance = s.irradiance;
    for (int v = 0; v < 60; ++v) irradiance[v] *= 0.1f;
    ASSERT_GE(DelightAlbedo(&twice, irradiance, d), 2);
    EXPECT_FLOAT_EQ(twice.albedo[0].maxCoeff(), 0.95f) << "the patch is clipped";
    const std::vector<Eigen::Vector3f> first = twice.albedo;
    DelightAlbedo(&twice, irradiance, d);
    for (std::size_t v = 0; v < first.size(); ++v) ASSERT_TRUE(twice.albedo[v].isApprox(first[v], 1e-5f)) << v;
  }

  // Unlit (0), NaN and negative irradiance: 5 % of the median stands in; the albedo stays
  // finite and clipped to 0.95 however bright the colour seen.
  s.irradiance[10] = 0;
  s.irradiance[11] = std::nanf("");
  s.irradiance[700] = -1;
  s.mesh.shaded[12] = Eigen::Vector3f::Constant(50.f);
  DelightAlbedo(&s.mesh, s.irradiance, d);
  for (const auto& a : s.mesh.albedo) {
    EXPECT_TRUE(a.allFinite());
    EXPECT_LE(a.maxCoeff(), 0.95f);
    EXPECT_GE(a.minCoeff(), 0.f);
  }
  // Nothing lit at all: nothing to divide by, the albedo is left as it was.
  Mesh dark = s.mesh;
  const auto kept = dark.albedo;
  EXPECT_EQ(DelightAlbedo(&dark, std::vector<float>(dark.positions.size(), 0.f), d), -1);
  EXPECT_EQ(dark.albedo, kept);
  // Nothing seen (every colour seen black, a hand-made bundle): the same, not a black mesh.
  Mesh unseen = s.mesh;
  for (auto& c : unseen.shaded) c.setZero();
  EXPECT_EQ(DelightAlbedo(&unseen, s.irradiance, d), -1);
  EXPECT_EQ(unseen.albedo, kept);
}

}  // namespace
}  // namespace lp
