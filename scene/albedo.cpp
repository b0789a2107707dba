#include "scene/albedo.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "common/error.h"
#include "scene/surface_filter.h"

namespace lp {

namespace {

struct Segments {
  std::vector<int> parent;
  std::vector<Eigen::Vector3d> sum;  // colour sums
  std::vector<int> count;

  int Find(int a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  }
  Eigen::Vector3d Mean(int root) const { return sum[root] / count[root]; }
};

Eigen::Vector3d Chroma(const Eigen::Vector3d& c) {
  const double s = c.sum();
  return s > 1e-6 ? Eigen::Vector3d(c / s) : Eigen::Vector3d::Constant(1.0 / 3);
}

bool Alike(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const AlbedoOptions& o) {
  return (Chroma(a) - Chroma(b)).norm() <= o.max_chroma_spread &&
         std::abs(std::log(std::max(1e-4, a.sum())) - std::log(std::max(1e-4, b.sum()))) <= o.max_log_spread;
}

/// Joins segments of at least min_segment vertices whose means are alike (within the
/// chromaticity spread and max_apart_log_spread) and that do not touch (a step across an
/// edge the joins kept apart is a material's): the largest first, each into the first
/// larger group it is alike to and touches nowhere. `edges`: the mesh's, each once.
void JoinApart(Segments* s, const std::vector<std::pair<int, int>>& edges, const AlbedoOptions& o) {
  std::vector<int> roots;
  for (int v = 0; v < static_cast<int>(s->parent.size()); ++v)
    if (s->Find(v) == v && s->count[v] >= o.min_segment) roots.push_back(v);
  std::sort(roots.begin(), roots.end(), [&](int a, int b) { return s->count[a] > s->count[b]; });
  std::vector<std::pair<int, int>> touching;  // segment roots that share an edge, (small, large)
  for (const auto& [a, b] : edges) {
    const int ra = s->Find(a), rb = s->Find(b);
    if (ra != rb) touching.emplace_back(std::min(ra, rb), std::max(ra, rb));
  }
  std::sort(touching.begin(), touching.end());
  touching.erase(std::unique(touching.begin(), touching.end()), touching.end());
  const auto touch = [&](int a, int b) {
    return std::binary_search(touching.begin(), touching.end(), std::make_pair(std::min(a, b), std::max(a, b)));
  };
  AlbedoOptions apart = o;
  apart.max_log_spread = o.max_apart_log_spread;
  std::vector<std::vector<int>> groups;  // each: its roots, the first the largest (the group's)
  for (int r : roots) {
    const auto into = std::find_if(groups.begin(), groups.end(), [&](const std::vector<int>& g) {
      return Alike(s->Mean(g.front()), s->Mean(r), apart) &&
             std::none_of(g.begin(), g.end(), [&](int m) { return touch(m, r); });
    });
    if (into == groups.end()) {
      groups.push_back({r});
      continue;
    }
    const int big = into->front();
    into->push_back(r);
    s->parent[r] = big;
    s->sum[big] += s->sum[r];
    s->count[big] += s->count[r];
  }
}

}  // namespace

int FlattenAlbedo(Mesh* mesh, const AlbedoOptions& o, std::vector<int>* labels) {
  if (labels) labels->assign(mesh->positions.size(), -1);
  if (!o.segment || mesh->albedo.size() != mesh->positions.size()) return 0;
  const int n = static_cast<int>(mesh->positions.size());
  struct Edge {
    float cost;
    int a, b;
  };
  std::vector<Edge> edges;
  edges.reserve(mesh->triangles.size() * 3 / 2 + 1);
  std::vector<std::pair<int, int>> pairs;
  pairs.reserve(mesh->triangles.size() * 3);
  for (const Eigen::Vector3i& t : mesh->triangles)
    for (int k = 0; k < 3; ++k) pairs.emplace_back(std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3]));
  std::sort(pairs.begin(), pairs.end());  // each edge once, boundary edges included
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  for (const auto& [a, b] : pairs) {
      const Eigen::Vector3d ca = mesh->albedo[a].cast<double>(), cb = mesh->albedo[b].cast<double>();
      const double chroma = (Chroma(ca) - Chroma(cb)).norm();
      const double log_step = std::abs(std::log(std::max(1e-4, ca.sum())) - std::log(std::max(1e-4, cb.sum())));
      if (chroma < o.max_chroma_step && log_step < o.max_log_step)
        edges.push_back({static_cast<float>(chroma / o.max_chroma_step + log_step / o.max_log_step), a, b});
    }
  // The smoothest joins first (Felzenszwalb-style), each checked against the segments' means.
  std::sort(edges.begin(), edges.end(), [](const Edge& x, const Edge& y) { return x.cost < y.cost; });
  Segments s;
  s.parent.resize(n);
  std::iota(s.parent.begin(), s.parent.end(), 0);
  s.count.assign(n, 1);
  s.sum.resize(n);
  for (int v = 0; v < n; ++v) s.sum[v] = mesh->albedo[v].cast<double>();
  for (const Edge& e : edges) {
    const int ra = s.Find(e.a), rb = s.Find(e.b);
    if (ra == rb) continue;
    if ((Chroma(s.Mean(ra)) - Chroma(s.Mean(rb))).norm() > o.max_chroma_spread) continue;
    if (std::abs(std::log(std::max(1e-4, s.Mean(ra).sum())) - std::log(std::max(1e-4, s.Mean(rb).sum()))) >
        o.max_log_spread)
      continue;
    const int big = s.count[ra] >= s.count[rb] ? ra : rb, small = big == ra ? rb : ra;
    s.parent[small] = big;
    s.sum[big] += s.sum[small];
    s.count[big] += s.count[small];
  }
  if (o.max_apart_log_spread > 0) JoinApart(&s, pairs, o);
  int flattened = 0;
  std::vector<int> index(n, -1);  // per root: its segment's number
  for (int v = 0; v < n; ++v) {
    const int r = s.Find(v);
    if (s.count[r] < o.min_segment) continue;
    mesh->albedo[v] = s.Mean(r).cast<float>();
    if (index[r] < 0) index[r] = flattened++;
    if (labels) (*labels)[v] = index[r];
  }
  return flattened;
}

AlbedoOptions DelitAlbedoOptions() {
  AlbedoOptions o;
  o.max_log_spread = o.max_log_step;
  o.max_apart_log_spread = o.max_log_step;
  return o;
}

namespace {

/// The vertices no segment flattened (label -1: a segment too small, a shadow's rim, a dark
/// box's face) keep their own de-lit colour: divided by the irradiance smoothed over the
/// surface (SmoothOverSurface), since a vertex's Monte Carlo noise would be its albedo's
/// (speckle on the lit mesh). The flattened segments' means average that noise out already.
void KeepSmoothlyDelit(Mesh* mesh, const std::vector<float>& irradiance, float floor, const std::vector<int>& labels) {
  const std::size_t n = mesh->positions.size();
  std::vector<Eigen::Vector3f> grey(n);
  bool any = false;
  for (std::size_t v = 0; v < n; ++v) {
    grey[v] = Eigen::Vector3f::Constant(std::isfinite(irradiance[v]) ? std::max(floor, irradiance[v]) : floor);
    any = any || labels[v] < 0;
  }
  if (!any) return;
  grey = SmoothOverSurface(*mesh, grey);
  for (std::size_t v = 0; v < n; ++v)
    if (labels[v] < 0) mesh->albedo[v] = mesh->shaded[v] / grey[v].x();
}

}  // namespace

int DelightAlbedo(Mesh* mesh, const std::vector<float>& irradiance, const AlbedoOptions& options, double scale,
                  double median, std::vector<int>* labels) {
  const std::size_t n = mesh->positions.size();
  LP_CHECK(mesh->shaded.size() == n && irradiance.size() == n && mesh->albedo.size() == n,
           "DelightAlbedo: shaded colours and irradiance per vertex");
  std::vector<float> sorted;
  sorted.reserve(n);
  for (float e : irradiance)
    if (std::isfinite(e) && e > 0) sorted.push_back(e);
  if (sorted.empty()) return -1;  // nothing lit: nothing to divide by
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const float floor = 0.05f * sorted[sorted.size() / 2];
  double before = 0, after = 0;  // the scale of the colours seen, whatever earlier passes did
  for (const Eigen::Vector3f& c : mesh->shaded) before += c.sum();
  if (!(before > 0) || !std::isfinite(before)) return -1;  // nothing seen (black colours)
  for (std::size_t v = 0; v < n; ++v) {
    const float e = std::isfinite(irradiance[v]) ? std::max(floor, irradiance[v]) : floor;
    mesh->albedo[v] = mesh->shaded[v] / e;  // grey: the colour seen keeps its chromaticity
  }
  std::vector<int> own_labels;
  if (!labels) labels = &own_labels;
  const int segments = FlattenAlbedo(mesh, options, labels);  // keeps each segment's sum: after > 0
  KeepSmoothlyDelit(mesh, irradiance, floor, *labels);
  for (const Eigen::Vector3f& a : mesh->albedo) after += a.sum();
  // The scale sets the interreflections. The rule the albedo was scaled by before (the
  // median): the mean colour seen, which flattening keeps, has the light's fall-off in it,
  // and a room under a near lamp (its colours' mean far above their median) came out with
  // most of its surface at the clip (docs/method.md, "The albedo's scale"). The de-lit
  // colours' long tail (unlit vertices) is clipped at kMaxAlbedo either way.
  ScaleAlbedo(mesh, median > 0 ? AlbedoScaleTo(*mesh, median) : scale * before / after);
  return segments;
}

double AlbedoScaleTo(const Mesh& mesh, double median) {
  if (!(median > 0) || mesh.albedo.empty()) return 1;
  std::vector<float> lum;
  lum.reserve(mesh.albedo.size());
  for (const Eigen::Vector3f& a : mesh.albedo) lum.push_back(0.2126f * a.x() + 0.7152f * a.y() + 0.0722f * a.z());
  const std::size_t k = lum.size() / 2;
  std::nth_element(lum.begin(), lum.begin() + k, lum.end());
  return lum[k] > 0 && std::isfinite(lum[k]) ? median / lum[k] : 1;
}

void ScaleAlbedo(Mesh* mesh, double scale) {
  const float s = static_cast<float>(scale);
  for (Eigen::Vector3f& a : mesh->albedo) a = (a * s).cwiseMax(0.f).cwiseMin(kMaxAlbedo);
}

}  // namespace lp
