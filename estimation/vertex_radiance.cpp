#include "estimation/vertex_radiance.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "common/color.h"
#include "common/error.h"
#include "common/parallel.h"
#include "common/rng.h"
#include "estimation/error_display.h"
#include "estimation/path_tracer.h"
#include "estimation/pixel_loop.h"
#include "estimation/lights/light.h"
#include "estimation/sampling.h"
#include "scene/surface_filter.h"

namespace lp {
namespace {
/// The path tracer's defaults: the same negligible throughput and Russian roulette.
const TracerOptions kPathEnds;
}  // namespace

VertexRadiance::VertexRadiance(const RayTracer& scene, const EnvMap& env, Lighting lighting, int bounces,
                               std::uint64_t seed)
    : scene_(scene), env_(env), lighting_(std::move(lighting)), bounces_(bounces), seed_(seed) {
  const std::vector<double>& map = lighting_.map;
  LP_CHECK(static_cast<int>(map.size()) == 3 * env.size(),
           "the map has " << map.size() << " values for " << env.size() << " cells");
  sampler_ = std::make_unique<CellSampler>(env, map, std::vector<std::uint8_t>{}, 0.05);
  LP_CHECK(bounces >= 1, "bounces " << bounces);
  sum_.assign(scene.mesh().positions.size(), Eigen::Vector3d::Zero());
  odd_ = sum_;
  square_.assign(sum_.size(), 0.0);
  count_.assign(sum_.size(), 0);
  const bool fixed_at_vertex = std::all_of(lighting_.lights.begin(), lighting_.lights.end(), [](const Light& light) {
    if (const auto* p = std::get_if<PointLight>(&light)) return p->radius == 0;
    if (const auto* d = std::get_if<DirectionalLight>(&light)) return d->angular_radius == 0;
    return false;
  });
  if (fixed_at_vertex && !lighting_.lights.empty()) at_vertex_.assign(sum_.size(), Eigen::Vector3d::Constant(NAN));
}

VertexRadiance::~VertexRadiance() = default;

void VertexRadiance::Refine(int samples) {
  RefineWhere(samples, nullptr);
  if (samples_ >= 0) samples_ += samples;
}

void VertexRadiance::Refine(int samples, const std::vector<std::uint8_t>& which) {
  LP_CHECK(which.size() == sum_.size(), "VertexRadiance::Refine: " << which.size() << " marks for " << sum_.size()
                                                                     << " vertices");
  RefineWhere(samples, which.data());
  samples_ = -1;
}

void VertexRadiance::RefineWhere(int samples, const std::uint8_t* which) {
  ParallelForChunks(0, sum_.size(), 256, [&](std::size_t b, std::size_t e) {
    for (std::size_t v = b; v < e; ++v)
      if (!which || which[v]) RefineVertex(v, samples);
  });
}

void VertexRadiance::RefineVertex(std::size_t v, int samples) {
  const Mesh& mesh = scene_.mesh();
  const int first = count_[v];
  count_[v] += samples;
  detail::Counters ended;  // how paths ended (not reported)
  if (v >= mesh.normals.size()) return;
  const Eigen::Vector3d n0 = mesh.normals[v].cast<double>();
  if (!(n0.squaredNorm() > 0.5)) return;
  const Eigen::Vector3d start = mesh.positions[v].cast<double>() + n0 * (4 * scene_.epsilon());
  // The stratified first bounce's random shift, per vertex and half (the even samples
  // and the odd, each shifted apart: independent halves, so Clean's noise stays what it
  // says).
  std::array<Eigen::Vector2d, 2> shift;
  if (stratified_)
    for (std::uint64_t h = 0; h < 2; ++h) {
      Rng r(seed_ ^ 0x9e3779b97f4a7c15ull, v, h);
      shift[h].x() = r.Uniform();
      shift[h].y() = r.Uniform();
    }
  for (int s = first; s < first + samples; ++s) {
    Rng rng(seed_, v, static_cast<std::uint64_t>(s));
    // The path tracer's conventions: leave a surface 4 epsilon along its geometric
    // normal, a direction the shading normal allows but the geometry faces away from is
    // absorbed, and next-event estimation towards a cell drawn by the estimate's
    // brightness is combined with cosine sampling by the power heuristic (the lit
    // shading of a small bright light converges in tens of samples, not thousands).
    Eigen::Vector3d origin = start;
    Eigen::Vector3d n = n0, geometric = n0, throughput = Eigen::Vector3d::Ones();
    const std::vector<double>& map = lighting_.map;
    Eigen::Vector3d got = Eigen::Vector3d::Zero();  // this path's incident radiance
    auto cell = [&](int j) { return Eigen::Vector3d(map[3 * j], map[3 * j + 1], map[3 * j + 2]); };
    for (int bounce = 0; bounce < bounces_; ++bounce) {
      const NextEvent ne = SampleNextEvent(scene_, env_, *sampler_, n, geometric, origin, rng);
      if (ne.visible) got += throughput.cwiseProduct(cell(ne.cell)) * ne.weight;
      if (bounce == 0 && !at_vertex_.empty() && !std::isnan(at_vertex_[v].x())) {
        got += at_vertex_[v];
      } else if (!lighting_.lights.empty()) {  // the lights' irradiance / pi
        const std::uint64_t key = (static_cast<std::uint64_t>(v) << 24) ^ (static_cast<std::uint64_t>(s) << 4) ^
                                  static_cast<std::uint64_t>(bounce);
        std::int64_t rays = 0;
        const Eigen::Vector3d lit =
            throughput.cwiseProduct(lp::Irradiance(scene_, lighting_.lights, origin, n, geometric, key, &rays)) *
            kInvPi;
        got += lit;
        if (bounce == 0 && !at_vertex_.empty()) at_vertex_[v] = lit;
      }
      double u1, u2;
      if (bounce == 0 && stratified_) {  // the s-th direction of its half
        Sobol2(static_cast<std::uint32_t>(s >> 1), &u1, &u2);
        u1 += shift[s & 1].x();
        u2 += shift[s & 1].y();
        u1 -= std::floor(u1);
        u2 -= std::floor(u2);
      } else {
        u1 = rng.Uniform();
        u2 = rng.Uniform();
      }
      const Eigen::Vector3d dir = SampleCosine(n, u1, u2);
      if (geometric.dot(dir) <= 0) break;
      SurfacePoint hit;
      if (!scene_.Intersect(origin, dir, &hit)) {
        const int j = env_.Lookup(dir);
        got += throughput.cwiseProduct(cell(j)) * EscapeWeight(env_, *sampler_, j, n.dot(dir), origin, dir);
        break;
      }
      // Cosine sampling cancels cos/pi against the Lambertian albedo/pi: the weight is the albedo.
      throughput = throughput.cwiseProduct(hit.albedo);
      if (!detail::PathContinues(bounce, kPathEnds, &throughput, rng, ended)) break;
      n = hit.shading;
      geometric = hit.geometric;
      origin = hit.position + hit.geometric * (4 * scene_.epsilon());
    }
    sum_[v] += got;
    square_[v] += got.mean() * got.mean();
    if (s & 1) odd_[v] += got;
  }
}

std::vector<Eigen::Vector3f> VertexRadiance::Radiance() const {
  const Mesh& mesh = scene_.mesh();
  std::vector<Eigen::Vector3f> out(sum_.size(), Eigen::Vector3f::Zero());
  for (std::size_t v = 0; v < out.size(); ++v)
    if (count_[v] > 0) out[v] = (mesh.albedo[v].cast<double>().cwiseProduct(sum_[v]) / count_[v]).cast<float>();
  return out;
}

LitShading VertexRadiance::Clean(const SurfaceFilter& filter) const {
  LP_CHECK(samples_ >= 2 && samples_ % 2 == 0, "VertexRadiance::Clean: " << samples_ << " samples (an even count)");
  const Mesh& mesh = scene_.mesh();
  const std::size_t n = sum_.size();
  const double half = samples_ / 2;
  // The lights' light at the vertex itself, where it is the same in every sample, is exact:
  // only the rest (the map's, and what surfaces send) is noise to smooth out. Smoothing the
  // whole would mix the direct light of neighbours whose normals differ (a scan's).
  std::vector<Eigen::Vector3f> exact(n, Eigen::Vector3f::Zero()), even(n), odd(n);
  for (std::size_t v = 0; v < n; ++v) {
    if (v < at_vertex_.size() && !std::isnan(at_vertex_[v].x())) exact[v] = at_vertex_[v].cast<float>();
    odd[v] = (odd_[v] / half).cast<float>() - exact[v];
    even[v] = ((sum_[v] - odd_[v]) / half).cast<float>() - exact[v];
  }
  FitAffineOverSurface(mesh, {&even, &odd}, filter);
  for (std::size_t v = 0; v < n; ++v) {
    even[v] += exact[v];
    odd[v] += exact[v];
  }
  LitShading out;
  out.radiance.resize(n);
  double diff2 = 0, level = 0;
  std::size_t counted = 0;
  const auto luminance = [](const Eigen::Vector3f& c) { return Luminance(c.x(), c.y(), c.z()); };
  for (std::size_t v = 0; v < n; ++v) {
    const Eigen::Vector3f& a = mesh.albedo[v];
    out.radiance[v] = a.cwiseProduct(0.5f * (even[v] + odd[v]));
    if (v >= mesh.normals.size() || !(mesh.normals[v].squaredNorm() > 0.5)) continue;  // never traced
    const double d = luminance(a.cwiseProduct(0.5f * (even[v] - odd[v])));
    diff2 += d * d;
    level += luminance(out.radiance[v]);
    ++counted;
  }
  out.noise = level > 0 ? std::sqrt(diff2 / counted) / (level / counted) : 0;
  // A glowing surface's own light, seen from the side its normal faces (not noise).
  if (lighting_.Count<EmitterLight>() > 0)
    for (std::size_t v = 0; v < n && v < mesh.normals.size(); ++v)
      out.radiance[v] += Emission(lighting_.lights, mesh.positions[v].cast<double>(), mesh.normals[v].cast<double>())
                             .cast<float>();
  return out;
}

std::vector<float> VertexRadiance::Irradiance() const {
  std::vector<float> out(sum_.size(), 0.f);
  for (std::size_t v = 0; v < out.size(); ++v)
    if (count_[v] > 0) out[v] = static_cast<float>(sum_[v].mean() / count_[v]);
  return out;
}

std::vector<float> VertexRadiance::IrradianceVariance() const {
  std::vector<float> out(sum_.size(), 0.f);
  for (std::size_t v = 0; v < out.size(); ++v) {
    const double k = count_[v];
    if (k < 2) continue;
    const double mean = sum_[v].mean() / k;
    out[v] = static_cast<float>(std::max(0.0, (square_[v] - k * mean * mean) / (k - 1)) / k);
  }
  return out;
}

std::vector<float> VertexPhotometricError(const RayTracer& scene, const std::vector<View>& views,
                                          const std::vector<Eigen::Vector3f>& radiance) {
  std::vector<float> white(views.size());
  for (std::size_t k = 0; k < views.size(); ++k) white[k] = WhiteLevel(views[k]);
  const Mesh& mesh = scene.mesh();
  LP_CHECK(radiance.size() == mesh.positions.size(), "radiance per vertex: " << radiance.size());
  std::vector<float> error(radiance.size(), std::nanf(""));
  ParallelForChunks(0, mesh.positions.size(), 256, [&](std::size_t b, std::size_t e) {
    for (std::size_t v = b; v < e; ++v) {
      const Eigen::Vector3d p = mesh.positions[v].cast<double>();
      double best = 1e300;
      for (std::size_t k = 0; k < views.size(); ++k) {
        const View& view = views[k];
        const Camera& cam = view.camera;
        double u, w;
        if (!cam.Project(p, &u, &w)) continue;
        const int x = static_cast<int>(std::lround(u)), y = static_cast<int>(std::lround(w));
        if (x < 0 || y < 0 || x >= cam.width || y >= cam.height) continue;
        const std::size_t i = static_cast<std::size_t>(y) * cam.width + x;
        if (!view.valid[i]) continue;
        const Eigen::Vector3d to = p - cam.center();
        const double dist = to.norm();
        if (!(dist > 0) || dist >= best) continue;
        SurfacePoint hit;
        if (scene.Intersect(cam.center(), to / dist, &hit) && hit.distance < 0.98 * dist) continue;
        best = dist;
        error[v] = PixelError(radiance[v].data(), &view.image.data[3 * i]) / white[k];
      }
    }
  });
  return error;
}

}  // namespace lp
