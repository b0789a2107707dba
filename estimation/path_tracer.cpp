#include "estimation/path_tracer.h"

#include <algorithm>
#include <atomic>
#include <cmath>

#include "common/color.h"
#include "common/error.h"
#include "common/parallel.h"
#include "common/rng.h"
#include "common/timer.h"
#include "estimation/pixel_loop.h"
#include "estimation/sampling.h"

namespace lp {

CellSampler::CellSampler(const EnvMap& env, const std::vector<double>& lambda,
                         const std::vector<std::uint8_t>& reachable, double floor) {
  const int L = env.size();
  std::vector<double> w(L, 0.0), area(L, 0.0);
  double wsum = 0, asum = 0;
  for (int j = 0; j < L; ++j) {
    if (!reachable.empty() && !reachable[j]) continue;
    area[j] = env.solid_angle(j);
    asum += area[j];
    if (!lambda.empty()) {
      const double lum = Luminance(lambda[3 * j], lambda[3 * j + 1], lambda[3 * j + 2]);
      w[j] = std::isfinite(lum) && lum > 0 ? lum * area[j] : 0.0;
      wsum += w[j];
    }
  }
  LP_CHECK(asum > 0, "no reachable cell to sample");
  const double eps = wsum > 0 ? std::clamp(floor, 0.0, 1.0) : 1.0;
  prob_.resize(L);
  cdf_.resize(L);
  double acc = 0;
  for (int j = 0; j < L; ++j) {
    prob_[j] = (wsum > 0 ? (1 - eps) * w[j] / wsum : 0.0) + eps * area[j] / asum;
    acc += prob_[j];
    cdf_[j] = acc;
  }
  for (int j = 0; j < L; ++j) {
    prob_[j] /= acc;
    cdf_[j] /= acc;
  }
}

void CellSampler::SetPortals(std::vector<Portal> portals, double share) {
  portals_.clear();
  portal_cdf_.clear();
  portal_area_ = 0;
  for (Portal& p : portals)
    if (p.Area() > 0) {
      portal_area_ += p.Area();
      portal_cdf_.push_back(portal_area_);
      portals_.push_back(std::move(p));
    }
  for (double& c : portal_cdf_) c /= portal_area_;
  portal_share_ = portals_.empty() ? 0.0 : std::clamp(share, 0.0, 1.0);
}

double CellSampler::Density(const EnvMap& env, int j, const Eigen::Vector3d& origin, const Eigen::Vector3d& w) const {
  const double cells = prob_[j] / env.solid_angle(j);
  if (portals_.empty()) return cells;
  double through = 0;  // the portals' density: distance^2 / (area x cosine) at each crossing
  for (const Portal& p : portals_) {
    double cos = 0;
    const double t = p.Crossing(origin, w, &cos);
    if (t > 0) through += t * t / (portal_area_ * cos);
  }
  return (1 - portal_share_) * cells + portal_share_ * through;
}

Eigen::Vector3d CellSampler::SampleDirection(const EnvMap& env, const Eigen::Vector3d& origin, double u0, double u1,
                                             double u2, int* cell) const {
  if (u0 < portal_share_) {  // (u0 reused: uniform again within the share)
    const double u = u0 / portal_share_;
    const std::size_t k = std::min<std::size_t>(
        std::upper_bound(portal_cdf_.begin(), portal_cdf_.end(), u) - portal_cdf_.begin(), portals_.size() - 1);
    const Eigen::Vector3d w = (portals_[k].Point(u1, u2) - origin).normalized();
    *cell = env.Lookup(w);
    return w;
  }
  *cell = Sample(portals_.empty() ? u0 : (u0 - portal_share_) / (1 - portal_share_));
  return env.SampleInCell(*cell, u1, u2);
}

int CellSampler::Sample(double u) const {
  const auto it = std::upper_bound(cdf_.begin(), cdf_.end(), u);
  int j = static_cast<int>(std::min<std::ptrdiff_t>(it - cdf_.begin(), cdf_.size() - 1));
  while (j > 0 && prob_[j] == 0) --j;  // guard against rounding at the end of the CDF
  return j;
}

NextEvent SampleNextEvent(const RayTracer& scene, const EnvMap& env, const CellSampler& sampler,
                          const Eigen::Vector3d& n, const Eigen::Vector3d& g, const Eigen::Vector3d& origin, Rng& rng) {
  NextEvent e;
  const double u0 = rng.Uniform(), u1 = rng.Uniform(), u2 = rng.Uniform();
  const Eigen::Vector3d w = sampler.SampleDirection(env, origin, u0, u1, u2, &e.cell);
  const double cos_s = n.dot(w);
  if (!(cos_s > 0 && g.dot(w) > 0)) return e;
  e.traced = true;
  if (scene.Occluded(origin, w)) return e;
  const double pdf_nee = sampler.Density(env, e.cell, origin, w);
  if (!(pdf_nee > 0)) return e;  // (a portal's edge rounded off it, in a cell never drawn)
  e.visible = true;
  const double pdf_bsdf = cos_s * kInvPi;
  const double mis = PowerHeuristic(pdf_nee, pdf_bsdf);
  e.weight = kInvPi * cos_s * mis / pdf_nee;
  return e;
}

double EscapeWeight(const EnvMap& env, const CellSampler& sampler, int j, double cos_n, const Eigen::Vector3d& origin,
                    const Eigen::Vector3d& w) {
  const double pdf_nee = sampler.Density(env, j, origin, w);
  return PowerHeuristic(cos_n * kInvPi, pdf_nee);
}

namespace {

using detail::Counters;
using detail::ForEachPixel;
using detail::PixelRef;
using detail::PixelsToTrace;
using detail::PathContinues;

/// One camera sample of pixel (x, y): calls sink(cell, rgb weight) for every
/// contribution; the pixel value is sum(weight * lambda_cell) / spp. At every surface
/// interaction it also calls vertex(hit, offset origin, throughput x albedo / pi) (lights
/// other than the map: RenderEnvironment's VertexLight).
template <class Sink, class VertexSink>
void TracePath(const RayTracer& scene, const EnvMap& env, const CellSampler& sampler, const Camera& cam, int x,
               int y, Rng& rng, const TracerOptions& opt, Counters& cnt, Sink&& sink, VertexSink&& vertex) {
  ++cnt.paths;
  Eigen::Vector3d origin = cam.center();
  Eigen::Vector3d dir = cam.RayDirection(x + rng.Uniform() - 0.5, y + rng.Uniform() - 0.5);
  Eigen::Vector3d T(1, 1, 1);
  SurfacePoint hit;
  ++cnt.rays;
  if (!scene.Intersect(origin, dir, &hit)) {
    sink(env.Lookup(dir), T);  // the camera sees the sky directly
    return;
  }
  const double eps = scene.epsilon();
  for (int bounce = 0;; ++bounce) {
    const Eigen::Vector3d& n = hit.shading;
    const Eigen::Vector3d rho = hit.albedo;
    const Eigen::Vector3d off = hit.position + hit.geometric * (4 * eps);
    vertex(hit, off, Eigen::Vector3d(T.cwiseProduct(rho) * kInvPi));
    // 1. Next-event estimation towards a cell.
    {
      const NextEvent e = SampleNextEvent(scene, env, sampler, n, hit.geometric, off, rng);
      cnt.rays += e.traced;
      if (e.visible) sink(e.cell, T.cwiseProduct(rho) * e.weight);
    }
    // 2. BSDF sampling: cosine-weighted, throughput *= albedo.
    const Eigen::Vector3d w = SampleCosine(n, rng.Uniform(), rng.Uniform());
    T = T.cwiseProduct(rho);
    if (hit.geometric.dot(w) <= 0) return;  // shading normal points past the geometry: absorbed
    ++cnt.rays;
    SurfacePoint next;
    if (!scene.Intersect(off, w, &next)) {
      const int j = env.Lookup(w);
      sink(j, T * EscapeWeight(env, sampler, j, n.dot(w), off, w));
      return;
    }
    if (bounce + 1 >= opt.bounces) {
      ++cnt.max_bounces;
      return;
    }
    if (!PathContinues(bounce, opt, &T, rng, cnt)) return;
    hit = next;
  }
}

constexpr auto NoVertex = [](const SurfacePoint&, const Eigen::Vector3d&, const Eigen::Vector3d&) {};

}  // namespace

TransportMatrix TraceTransport(const RayTracer& scene, const EnvMap& env, const std::vector<View>& views,
                               const CellSampler& sampler, const TracerOptions& opt, TraceStats* stats) {
  detail::CheckPathOptions(opt);
  Stopwatch sw;
  const std::vector<PixelRef> pixels = PixelsToTrace(views, false);
  std::vector<std::vector<std::pair<int, std::array<float, 3>>>> rows(pixels.size());
  ForEachPixel(pixels, opt, stats, [&](std::size_t i, const PixelRef& px, Counters& cnt) {
    const Camera& cam = views[px.view].camera;
    const int x = px.pixel % cam.width, y = px.pixel / cam.width;
    std::vector<std::pair<int, Eigen::Vector3d>> entries;
    for (int s = 0; s < opt.spp; ++s) {
      Rng rng(opt.seed, px.view, px.pixel, s);
      TracePath(scene, env, sampler, cam, x, y, rng, opt, cnt,
                [&](int j, const Eigen::Vector3d& wgt) { entries.emplace_back(j, wgt); }, NoVertex);
    }
    std::stable_sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    auto& row = rows[i];
    const double inv = 1.0 / opt.spp;
    for (std::size_t k = 0; k < entries.size();) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      const int j = entries[k].first;
      for (; k < entries.size() && entries[k].first == j; ++k) sum += entries[k].second;
      sum *= inv;
      if (sum.maxCoeff() > 0)
        row.push_back({j, {static_cast<float>(sum[0]), static_cast<float>(sum[1]), static_cast<float>(sum[2])}});
    }
  });
  TransportMatrix A;
  A.cells = env.size();
  A.samples = opt.spp;
  A.row_view.reserve(pixels.size());
  A.row_pixel.reserve(pixels.size());
  A.row_start.reserve(pixels.size() + 1);
  A.row_start.push_back(0);
  std::size_t nnz = 0;
  for (const auto& r : rows) nnz += r.size();
  A.col.reserve(nnz);
  A.val.reserve(nnz);
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    A.row_view.push_back(pixels[i].view);
    A.row_pixel.push_back(pixels[i].pixel);
    for (const auto& [j, v] : rows[i]) {
      A.col.push_back(j);
      A.val.push_back(v);
    }
    A.row_start.push_back(static_cast<std::int64_t>(A.col.size()));
    std::vector<std::pair<int, std::array<float, 3>>>().swap(rows[i]);
  }
  if (stats) {
    stats->pixels_traced += static_cast<std::int64_t>(pixels.size());
    std::int64_t total = 0;
    for (const View& v : views) total += static_cast<std::int64_t>(v.camera.width) * v.camera.height;
    stats->pixels_skipped += total - static_cast<std::int64_t>(pixels.size());
    stats->seconds += sw.Seconds();
  }
  return A;
}

std::vector<ImageRGB> RenderEnvironment(const RayTracer& scene, const EnvMap& env, const std::vector<View>& views,
                                        const std::vector<double>& lambda, const CellSampler& sampler,
                                        const TracerOptions& opt, bool all_pixels, TraceStats* stats) {
  return RenderEnvironment(scene, env, views, lambda, sampler, opt, all_pixels, VertexLight(), stats);
}

std::vector<ImageRGB> RenderEnvironment(const RayTracer& scene, const EnvMap& env, const std::vector<View>& views,
                                        const std::vector<double>& lambda, const CellSampler& sampler,
                                        const TracerOptions& opt, bool all_pixels, const VertexLight& lights,
                                        TraceStats* stats, const SeenLight& seen) {
  detail::CheckPathOptions(opt);
  LP_CHECK(lambda.size() == 3 * static_cast<std::size_t>(env.size()), "lambda size");
  Stopwatch sw;
  std::vector<ImageRGB> out;
  for (const View& v : views) out.emplace_back(v.camera.width, v.camera.height);
  const std::vector<PixelRef> pixels = PixelsToTrace(views, all_pixels);
  ForEachPixel(pixels, opt, stats, [&](std::size_t, const PixelRef& px, Counters& cnt) {
    const Camera& cam = views[px.view].camera;
    const int x = px.pixel % cam.width, y = px.pixel / cam.width;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int s = 0; s < opt.spp; ++s) {
      Rng rng(opt.seed, px.view, px.pixel, s);
      const auto cell = [&](int j, const Eigen::Vector3d& wgt) {
        sum += wgt.cwiseProduct(Eigen::Vector3d(lambda[3 * j], lambda[3 * j + 1], lambda[3 * j + 2]));
      };
      if (!lights && !seen) {
        TracePath(scene, env, sampler, cam, x, y, rng, opt, cnt, cell, NoVertex);
        continue;
      }
      std::uint64_t key = (static_cast<std::uint64_t>(px.pixel) << 32) ^ (static_cast<std::uint64_t>(s) << 8);
      bool first = true;
      TracePath(scene, env, sampler, cam, x, y, rng, opt, cnt, cell,
                [&](const SurfacePoint& hit, const Eigen::Vector3d& off, const Eigen::Vector3d& w) {
                  if (first && seen) sum += seen(hit);
                  ++key;
                  if (lights && (!first || opt.first_vertex_lights)) sum += w.cwiseProduct(lights(hit, off, key, cnt.rays));
                  first = false;
                });
    }
    float* p = out[px.view].at(x, y);
    for (int c = 0; c < 3; ++c) p[c] = static_cast<float>(sum[c] / opt.spp);
  });
  if (stats) {
    stats->pixels_traced += static_cast<std::int64_t>(pixels.size());
    stats->seconds += sw.Seconds();
  }
  return out;
}

}  // namespace lp
