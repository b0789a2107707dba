// The clean render's denoiser (estimation/render_denoise.h) against closed forms, and the
// render it takes (the lights' light at a path's first vertex left to the guide).
#include <algorithm>
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "common/rng.h"
#include "estimation/light_render.h"
#include "estimation/render_denoise.h"
#include "estimation/lights/light.h"
#include "tests/test_util.h"

namespace lp {
namespace {

// An irradiance affine in the pixel's place and in its normal: with the slopes free (no
// ridge) it comes back as it was, at the floor's edge in view (windows on one side of the
// pixel) as in its middle. With the default ridge the fit follows the gradient and the
// normals' tilt far better than a plain mean of the window (the slopes held at 0 by a huge
// ridge), and the error left on a noisy image is smaller too.
TEST(Denoiser, AnIrradianceAffineInThePlaceAndTheNormalComesBackAsItWas) {
  const RayTracer scene(test::FineFloor(0.5, 10 * M_PI / 180));
  const Camera cam = test::LookAt({0.25, 0.1, 0.6}, {0.25, 0.1, 0}, 64, 48, 70);  // the floor's edge at x = 0.5 in view
  const Eigen::Vector3d d = Eigen::Vector3d(1, -0.5, 0).normalized();  // along the floor: its first order is the tilt
  const PixelGuide g = GuideOf(scene, cam, {});
  const auto affine = [&](std::size_t i) {
    const double x = static_cast<double>(i % g.width), y = static_cast<double>(i / g.width);
    return 1 + 0.01 * x + 0.008 * y + 0.5 * g.normal[i].cast<double>().normalized().dot(d);
  };
  ImageRGB clean(cam.width, cam.height), noisy = clean;
  Rng rng(3);
  for (std::size_t i = 0; i < clean.pixels(); ++i)
    for (int c = 0; c < 3; ++c) {
      clean.data[3 * i + c] = static_cast<float>(g.albedo[i][c] * affine(i));
      noisy.data[3 * i + c] = clean.data[3 * i + c] * static_cast<float>(1 + 0.05 * std::sqrt(12.0) * (rng.Uniform() - 0.5));
    }
  struct Outcome {
    double worst = 0, rms = 0, noise_left = 0;
  };
  const auto run = [&](double ridge) {
    DenoiseOptions o;
    if (ridge >= 0) o.pixel_ridge = o.normal_ridge = ridge;
    const Denoiser denoise(g, cam.center(), o);
    const ImageRGB a = denoise(clean), b = denoise(noisy);
    Outcome out;
    int used = 0, by_the_edge = 0;
    for (std::size_t i = 0; i < clean.pixels(); ++i) {
      if (!(g.hit_share[i] >= 1.f) || g.fine[i]) continue;
      ++used;
      by_the_edge += static_cast<int>(i % cam.width) + 4 < cam.width && !(g.hit_share[i + 4] >= 1.f);
      const double e = a.data[3 * i] / clean.data[3 * i] - 1.0;
      out.worst = std::max(out.worst, std::abs(e));
      out.rms += e * e;
      out.noise_left += std::pow(b.data[3 * i] / clean.data[3 * i] - 1.0, 2);
    }
    out.rms = std::sqrt(out.rms / used);
    out.noise_left = std::sqrt(out.noise_left / used);
    std::printf("ridge %g: %d pixels (%d within 4 of the floor's edge): error worst %.4f, RMS %.4f; noise 0.05 -> %.4f\n",
                ridge, used, by_the_edge, out.worst, out.rms, out.noise_left);
    EXPECT_GT(used, 2000);
    EXPECT_GT(by_the_edge, 100);
    return out;
  };
  const Outcome exact = run(0), fit = run(-1 /* the default */), mean = run(1e6);
  EXPECT_LT(exact.worst, 2e-3);
  EXPECT_LT(fit.rms, mean.rms / 2);
  EXPECT_LT(fit.worst, mean.worst / 2);
  EXPECT_LT(fit.noise_left, 0.05 / 3.5);
  EXPECT_LT(fit.noise_left, mean.noise_left);  // (the error on the noisy image: noise and bias)
}

// A render without the lights' light at the first vertex, plus the guide's direct light,
// is the whole render: block by block over a floor with a square's soft shadow from a
// sphere lamp, under a dim sky, within the blocks' noise.
TEST(Denoiser, TheRenderWithoutTheFirstVertexLightsPlusTheGuidesDirectIsTheWholeRender) {
  Mesh mesh = test::FineFloor(0.5);
  mesh.Append(test::Square(0.05, 0, 0.15, 0.1, 0.6));
  const RayTracer scene(mesh);
  const EnvMap env(7, Eigen::Vector3d::UnitZ());
  const Lighting lighting{std::vector<double>(3 * env.size(), 0.05), {PointLight{{0.2, -0.1, 0.6}, {1.0, 1.0, 1.0}, 0.05}}};
  const CellSampler sampler(env, lighting.map, {}, 0.2);
  const std::vector<View> views{test::BlankView(test::LookAt({0, 0.05, 0.9}, {0, 0, 0}, 48, 48, 60))};
  TracerOptions t;
  t.spp = 256;
  t.bounces = 3;
  const ImageRGB whole = RenderLighting(scene, env, lighting, sampler, views, t, true)[0];
  t.first_vertex_lights = false;
  t.seed = 2;
  const ImageRGB rest = RenderLighting(scene, env, lighting, sampler, views, t, true)[0];
  t.seed = 3;
  const ImageRGB rest2 = RenderLighting(scene, env, lighting, sampler, views, t, true)[0];
  const PixelGuide g = GuideOf(scene, views[0].camera, lighting.lights);
  double worst = 0, mean_direct = 0, mean_rest = 0;
  for (int by = 0; by < 48; by += 8)
    for (int bx = 0; bx < 48; bx += 8) {
      double w = 0, r = 0, r2 = 0, dir = 0;
      for (int y = by; y < by + 8; ++y)
        for (int x = bx; x < bx + 8; ++x) {
          const std::size_t i = static_cast<std::size_t>(y) * 48 + x;
          w += whole.data[3 * i] / 64;
          r += rest.data[3 * i] / 64;
          r2 += rest2.data[3 * i] / 64;
          dir += g.direct[i][0] / 64;
        }
      mean_direct += dir / 36;
      mean_rest += r / 36;
      // The whole render's block against the rest plus the direct light, in units of the
      // rest's noise there (two seeds' difference; the whole render's own noise is alike).
      const double sigma = std::max(std::abs(r - r2), 0.002 * w);
      worst = std::max(worst, std::abs(w - r - dir) / sigma);
    }
  std::printf("direct %.4f, the rest %.4f (a block mean); worst block %.1f sigma\n", mean_direct, mean_rest, worst);
  EXPECT_GT(mean_direct, 3 * mean_rest) << "the lamp's direct light dominates: the test would see it missing";
  EXPECT_LT(worst, 6);
}

}  // namespace
}  // namespace lp
