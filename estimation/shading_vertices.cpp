#include "estimation/shading_vertices.h"

#include "common/error.h"
#include "estimation/pixel_loop.h"

namespace lp {

using detail::Counters;
using detail::ForEachPixel;
using detail::PixelRef;
using detail::PixelsToTrace;
using detail::CheckPathOptions;
using detail::WalkPath;

ShadingVertices GatherShadingVertices(const RayTracer& scene, const std::vector<View>& views,
                                      const TracerOptions& opt, bool all_pixels, TraceStats* stats) {
  CheckPathOptions(opt);
  struct Vertex {
    Eigen::Vector3f p, n, g, w;
    float camera;
    std::int8_t half, part;
  };
  const std::vector<PixelRef> pixels = PixelsToTrace(views, all_pixels);
  std::vector<std::vector<Vertex>> rows(pixels.size());
  const float inv = 1.0f / opt.spp;
  const int paired = opt.spp / 2 * 2;  // an odd count's last sample is in neither half
  const int dealt = opt.spp / kPathParts * kPathParts;  // nor the last of a count not dealt evenly in any part
  ForEachPixel(pixels, opt, stats, [&](std::size_t i, const PixelRef& px, Counters& cnt) {
    const Camera& cam = views[px.view].camera;
    const int x = px.pixel % cam.width, y = px.pixel / cam.width;
    for (int s = 0; s < opt.spp; ++s) {
      Rng rng(opt.seed, px.view, px.pixel, s);
      float camera = inv;  // the path's first vertex only
      const std::int8_t half = s >= paired ? 0 : s % 2 ? -1 : 1;
      const auto part = static_cast<std::int8_t>(s >= dealt ? -1 : s % kPathParts);
      WalkPath(scene, cam, x, y, rng, opt, cnt,
               [&](const SurfacePoint& hit, const Eigen::Vector3d& off, const Eigen::Vector3d& w) {
                 rows[i].push_back({off.cast<float>(), hit.shading.cast<float>(), hit.geometric.cast<float>(),
                                    w.cast<float>() * inv, camera, half, part});
                 camera = 0;
               });
    }
  });
  ShadingVertices out;
  std::size_t n = 0;
  for (const auto& r : rows) n += r.size();
  out.row_start.reserve(rows.size() + 1);
  out.position.reserve(n);
  out.normal.reserve(n);
  out.geometric.reserve(n);
  out.weight.reserve(n);
  out.camera.reserve(n);
  out.half.reserve(n);
  out.part.reserve(n);
  for (auto& r : rows) {
    for (const Vertex& v : r) {
      out.position.push_back(v.p);
      out.normal.push_back(v.n);
      out.geometric.push_back(v.g);
      out.weight.push_back(v.w);
      out.camera.push_back(v.camera);
      out.half.push_back(v.half);
      out.part.push_back(v.part);
    }
    out.row_start.push_back(static_cast<std::int64_t>(out.position.size()));
    std::vector<Vertex>().swap(r);
  }
  if (stats) stats->pixels_traced += static_cast<std::int64_t>(pixels.size());
  return out;
}

namespace {
/// Appends `v`'s vertex k to `out`, its weights (and its camera weight where `camera`)
/// times `w`; its half is the caller's to append.
void Append(ShadingVertices* out, const ShadingVertices& v, std::int64_t k, float w, bool camera) {
  out->position.push_back(v.position[k]);
  out->normal.push_back(v.normal[k]);
  out->geometric.push_back(v.geometric[k]);
  out->weight.push_back(v.weight[k] * w);
  if (camera) out->camera.push_back(v.camera[k] * w);
}
}  // namespace

ShadingVertices Combine(const ShadingVertices& a, double a_samples, const ShadingVertices& b, double b_samples) {
  LP_CHECK(a.rows() == b.rows(), "combining gatherings of different rows");
  const double n = a_samples + b_samples;
  LP_CHECK(n > 0, "no samples");
  const float wa = static_cast<float>(a_samples / n), wb = static_cast<float>(b_samples / n);
  ShadingVertices out;
  const std::size_t total = a.size() + b.size();
  out.row_start.reserve(a.rows() + 1);
  out.position.reserve(total);
  out.normal.reserve(total);
  out.geometric.reserve(total);
  out.weight.reserve(total);
  const bool camera = a.camera.size() == a.size() && b.camera.size() == b.size();
  if (camera) out.camera.reserve(total);
  const bool half = a.half.size() == a.size() && b.half.size() == b.size();
  if (half) out.half.reserve(total);
  const bool part = a.part.size() == a.size() && b.part.size() == b.size();
  if (part) out.part.reserve(total);
  for (std::size_t r = 0; r < a.rows(); ++r) {
    for (const auto& [v, w] : {std::pair<const ShadingVertices*, float>{&a, wa}, {&b, wb}})
      for (std::int64_t k = v->row_start[r]; k < v->row_start[r + 1]; ++k) {
        Append(&out, *v, k, w, camera);
        if (half) out.half.push_back(v->half[k]);
        if (part) out.part.push_back(v->part[k]);
      }
    out.row_start.push_back(static_cast<std::int64_t>(out.position.size()));
  }
  return out;
}

namespace {
/// The vertices `keep(k)` takes, their weights times `w`, their halves 0 (a subset's halves are
/// not its paths' halves).
template <class Keep>
ShadingVertices Subset(const ShadingVertices& v, Keep keep, float w) {
  const bool camera = v.camera.size() == v.size();
  ShadingVertices out;
  out.row_start.reserve(v.rows() + 1);
  for (std::size_t r = 0; r < v.rows(); ++r) {
    for (std::int64_t k = v.row_start[r]; k < v.row_start[r + 1]; ++k) {
      if (!keep(k)) continue;
      Append(&out, v, k, w, camera);
      out.half.push_back(0);
    }
    out.row_start.push_back(static_cast<std::int64_t>(out.position.size()));
  }
  return out;
}
}  // namespace

ShadingVertices HalfOf(const ShadingVertices& v, int half) {
  LP_CHECK(v.half.size() == v.size(), "HalfOf: the vertices' halves were not kept");
  return Subset(v, [&](std::int64_t k) { return v.half[k] == half; }, 2.f);
}

ShadingVertices PartOf(const ShadingVertices& v, int part) {
  LP_CHECK(v.part.size() == v.size(), "PartOf: the vertices' parts were not kept");
  return Subset(v, [&](std::int64_t k) { return v.part[k] == part; }, static_cast<float>(kPathParts));
}

}  // namespace lp
