#include "estimation/lights/emitter_light.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>

#include "common/parallel.h"
#include "estimation/lights/sphere_frame.h"
#include "estimation/sampling.h"

namespace lp {
namespace {

std::uint64_t CellKey(const Eigen::Vector3d& p, double cell) {
  const auto index = [&](double x) {
    return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(x / cell)) + (1 << 20)) & 0x1FFFFF;
  };
  return index(p.x()) | index(p.y()) << 21 | index(p.z()) << 42;
}

/// A point of the shape drawn by area from `u` (uniform in [0, 1)) and `v` (another).
Eigen::Vector3d PointOn(const EmitterShape& s, double u, double v, int* triangle) {
  const double at = u * s.area;
  const int t = static_cast<int>(
      std::min<std::ptrdiff_t>(std::upper_bound(s.cumulative.begin(), s.cumulative.end(), at) - s.cumulative.begin(),
                               static_cast<std::ptrdiff_t>(s.cumulative.size()) - 1));
  const double before = t > 0 ? s.cumulative[t - 1] : 0.0, own = s.cumulative[t] - before;
  const double w = own > 0 ? std::clamp((at - before) / own, 0.0, 1.0) : 0.5;  // re-used: uniform again
  const double r = std::sqrt(w);
  *triangle = t;
  return ((1 - r) * s.a[t].cast<double>() + r * (1 - v) * s.b[t].cast<double>() + r * v * s.c[t].cast<double>());
}

/// The light a unit-radiance emitter sends to p (normals n, g) through the point q of
/// triangle t: cos at p x cos at q / d^2, shadowed (the ray stops a cell short of q: the
/// traced surface may lie a little off the emitter's triangles), 0 behind either side.
double Transfer(const RayTracer& scene, const EmitterShape& s, const Eigen::Vector3d& p, const Eigen::Vector3d& n,
                const Eigen::Vector3d& g, const Eigen::Vector3d& q, int t) {
  const Eigen::Vector3d r = q - p;
  const double d2 = r.squaredNorm();
  if (!(d2 > 0)) return 0;
  const double d = std::sqrt(d2);
  const Eigen::Vector3d l = r / d;
  const double cx = n.dot(l), ce = -s.normal[t].cast<double>().dot(l);
  if (!(cx > 0 && g.dot(l) > 0 && ce > 0)) return 0;
  const double reach = d - s.cell;
  if (reach > 0 && scene.Occluded(p, l, reach)) return 0;
  return cx * ce / d2;
}

}  // namespace

std::shared_ptr<const EmitterShape> MakeEmitterShape(const Mesh& mesh, const std::vector<int>& triangles,
                                                     const std::vector<Eigen::Vector3f>& facing) {
  auto s = std::make_shared<EmitterShape>();
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    const Eigen::Vector3i& f = mesh.triangles[triangles[i]];
    const Eigen::Vector3f a = mesh.positions[f[0]], b = mesh.positions[f[1]], c = mesh.positions[f[2]];
    Eigen::Vector3f n = (b - a).cross(c - a);
    const double area = 0.5 * n.norm();
    if (!(area > 0) || !std::isfinite(area)) continue;
    n.normalize();
    if (i < facing.size() && n.dot(facing[i]) < 0) n = -n;
    s->a.push_back(a);
    s->b.push_back(b);
    s->c.push_back(c);
    s->normal.push_back(n);
    s->area += area;
    s->cumulative.push_back(s->area);
    // Its cells: points of the triangle no more than half a cell apart, and half a cell
    // either side along its normal.
    const int t = static_cast<int>(s->a.size()) - 1;
    const int steps = std::max(1, static_cast<int>(std::ceil(2 * std::max({(b - a).norm(), (c - a).norm(), (c - b).norm()}) / s->cell)));
    for (int i1 = 0; i1 <= steps; ++i1)
      for (int i2 = 0; i1 + i2 <= steps; ++i2) {
        const Eigen::Vector3d p = (a + (b - a) * (float(i1) / steps) + (c - a) * (float(i2) / steps)).cast<double>();
        for (int side = -1; side <= 1; ++side) {
          std::vector<int>& in = s->cells[CellKey(p + side * 0.5 * s->cell * n.cast<double>(), s->cell)];
          if (in.empty() || in.back() != t) in.push_back(t);
        }
      }
  }
  return s;
}

namespace {

/// Whether `point` lies within half a cell of triangle t's plane, inside its edges (by a millimetre).
bool OnTriangle(const EmitterShape& shape, int t, const Eigen::Vector3d& point) {
  constexpr double kEdge = 1e-3;  // metres inside a triangle's edges
  const Eigen::Vector3d n = shape.normal[t].cast<double>(), a = shape.a[t].cast<double>();
  if (std::abs(n.dot(point - a)) > 0.5 * shape.cell) return false;
  const Eigen::Vector3d corner[3] = {a, shape.b[t].cast<double>(), shape.c[t].cast<double>()};
  for (int e = 0; e < 3; ++e) {
    const Eigen::Vector3d edge = corner[(e + 1) % 3] - corner[e], out = edge.cross(n).normalized();
    // (`out` points away from the triangle when the corners run counter-clockwise about n)
    const double side = (corner[(e + 2) % 3] - corner[e]).dot(out) > 0 ? -1.0 : 1.0;
    if (side * out.dot(point - corner[e]) > kEdge) return false;
  }
  return true;
}

}  // namespace

bool OnEmitter(const EmitterShape& shape, const Eigen::Vector3d& point, const Eigen::Vector3d& towards_viewer) {
  const auto it = shape.cells.find(CellKey(point, shape.cell));
  if (it == shape.cells.end()) return false;
  for (int t : it->second)
    if (shape.normal[t].cast<double>().dot(towards_viewer) > 0 && OnTriangle(shape, t, point)) return true;
  return false;
}

int EmitterTriangleAt(const EmitterShape& shape, const Eigen::Vector3d& point) {
  const auto it = shape.cells.find(CellKey(point, shape.cell));
  if (it == shape.cells.end()) return -1;
  for (int t : it->second)
    if (OnTriangle(shape, t, point)) return t;
  return -1;
}

Eigen::Vector3d TriangleCentre(const Mesh& mesh, std::size_t t) {
  const Eigen::Vector3i& f = mesh.triangles[t];
  return ((mesh.positions[f[0]] + mesh.positions[f[1]] + mesh.positions[f[2]]) / 3).cast<double>();
}

std::vector<std::uint8_t> TrianglesOnShapes(const Mesh& mesh,
                                            const std::vector<std::shared_ptr<const EmitterShape>>& shapes) {
  std::vector<std::uint8_t> on(mesh.triangles.size(), 0);
  for (std::size_t t = 0; t < on.size() && !shapes.empty(); ++t) {
    const Eigen::Vector3d centre = TriangleCentre(mesh, t);
    for (const auto& s : shapes)
      if (s && EmitterTriangleAt(*s, centre) >= 0) on[t] = 1;
  }
  return on;
}

Mesh WithoutShapes(const Mesh& mesh, const std::vector<std::shared_ptr<const EmitterShape>>& shapes) {
  return WithoutTriangles(mesh, TrianglesOnShapes(mesh, shapes));
}

std::shared_ptr<const EmitterShape> ShapeOnMesh(const Mesh& mesh, const EmitterShape& shape,
                                                std::vector<std::uint8_t>* taken) {
  std::vector<int> triangles;
  std::vector<Eigen::Vector3f> facing;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    if (taken && t < taken->size() && (*taken)[t]) continue;
    if (const int on = EmitterTriangleAt(shape, TriangleCentre(mesh, t)); on >= 0) {
      if (taken && t < taken->size()) (*taken)[t] = 1;
      triangles.push_back(static_cast<int>(t));
      facing.push_back(shape.normal[on]);
    }
  }
  return triangles.empty() ? nullptr : MakeEmitterShape(mesh, triangles, facing);
}

Eigen::Vector3d FacingSum(const EmitterShape& s) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double previous = 0;
  for (std::size_t t = 0; t < s.a.size(); ++t) {
    sum += (s.cumulative[t] - previous) * s.normal[t].cast<double>();
    previous = s.cumulative[t];
  }
  return sum;
}

Eigen::Vector3d Centroid(const EmitterShape& s) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double previous = 0;
  for (std::size_t t = 0; t < s.a.size(); ++t) {
    sum += (s.cumulative[t] - previous) * ((s.a[t] + s.b[t] + s.c[t]) / 3.0f).cast<double>();
    previous = s.cumulative[t];
  }
  return s.area > 0 ? Eigen::Vector3d(sum / s.area) : Eigen::Vector3d::Zero();
}

std::vector<OutlineEdge> Outline(const EmitterShape& s) {
  using Corner = std::array<float, 3>;
  const auto corner = [](const Eigen::Vector3f& p) { return Corner{p.x(), p.y(), p.z()}; };
  std::map<std::pair<Corner, Corner>, std::pair<int, OutlineEdge>> edges;  // each edge, both ways the same key
  for (std::size_t t = 0; t < s.a.size(); ++t) {
    const Eigen::Vector3f* v[3] = {&s.a[t], &s.b[t], &s.c[t]};
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3f &p = *v[k], &q = *v[(k + 1) % 3];
      const Corner cp = corner(p), cq = corner(q);
      auto [it, added] = edges.try_emplace(cp < cq ? std::make_pair(cp, cq) : std::make_pair(cq, cp), 0,
                                           OutlineEdge{p, q, s.normal[t]});
      ++it->second.first;
    }
  }
  std::vector<OutlineEdge> outline;
  for (const auto& [key, edge] : edges)
    if (edge.first == 1) outline.push_back(edge.second);
  return outline;
}

double AreaOn(const EmitterShape& a, const EmitterShape& b, double within) {
  constexpr int kGrid = 60;
  // (a point within `within` of b's plane is within half a cell of it once moved along a's
  // normal by one of the offsets, a cell apart at most, up to the rest either way)
  const double shift = std::max(0.0, within - 0.5 * b.cell);
  const int steps = static_cast<int>(std::ceil(shift / b.cell));
  double on = 0, all = 0;
  for (std::size_t t = 0; t < a.a.size(); ++t) {
    const Eigen::Vector3d p0 = a.a[t].cast<double>(), e1 = (a.b[t] - a.a[t]).cast<double>(),
                          e2 = (a.c[t] - a.a[t]).cast<double>(), n = a.normal[t].cast<double>();
    const double w = e1.cross(e2).norm();
    for (int i = 0; i < kGrid; ++i)
      for (int j = 0; i + j < kGrid; ++j) {
        const Eigen::Vector3d p = p0 + e1 * ((i + 1.0 / 3) / kGrid) + e2 * ((j + 1.0 / 3) / kGrid);
        all += w;
        bool hit = false;
        for (int k = -steps; k <= steps && !hit; ++k) {
          const Eigen::Vector3d q = p + (steps > 0 ? shift * k / steps : 0.0) * n;
          hit = OnEmitter(b, q, n) || OnEmitter(b, q, -n);
        }
        on += w * hit;
      }
  }
  return all > 0 ? on / all : 0.0;
}

Eigen::Vector3d EmitterLight::Power() const { return kPi * radiance * Area(); }

void UnitColumn(const RayTracer& scene, const ShadingVertices& v, const EmitterLight& light, const ColumnOut& out) {
  const std::size_t rows = v.rows();
  out.Assign(rows);
  if (!light.shape || !(light.shape->area > 0)) return;
  const EmitterShape& s = *light.shape;
  const bool seen = v.camera.size() == v.size() && !light.in_a_hole;
  ParallelForChunks(0, rows, 64, [&](std::size_t b, std::size_t e) {
    for (std::size_t r = b; r < e; ++r) {
      ColumnRow row;
      for (std::int64_t k = v.row_start[r]; k < v.row_start[r + 1]; ++k) {
        const Eigen::Vector3d p = v.position[k].cast<double>(), n = v.normal[k].cast<double>(),
                              g = v.geometric[k].cast<double>();
        if (seen && v.camera[k] > 0 && OnEmitter(s, p, g)) row.Add(v.Half(k), Eigen::Vector3d::Constant(v.camera[k]));
        const double turn = HashUnit(static_cast<std::uint64_t>(k) * 0x9E3779B9ull + 17);
        double e_sum = 0;
        for (int i = 0; i < kEmitterShadowRays; ++i) {
          int t = 0;
          const Eigen::Vector3d q =
              PointOn(s, (i + turn) / kEmitterShadowRays, HashUnit(static_cast<std::uint64_t>(k) << 3 ^ i), &t);
          e_sum += Transfer(scene, s, p, n, g, q, t);
        }
        row.Add(v.Half(k), v.weight[k].cast<double>() * std::min(e_sum * s.area / kEmitterShadowRays, kPi));
      }
      row.Store(r, out);
    }
  });
}

Eigen::Vector3d Irradiance(const RayTracer& scene, const EmitterLight& light, const Eigen::Vector3d& origin,
                           const Eigen::Vector3d& n, const Eigen::Vector3d& g, std::uint64_t key,
                           std::int64_t* rays) {
  if (!light.shape || !(light.shape->area > 0)) return Eigen::Vector3d::Zero();
  int t = 0;
  const Eigen::Vector3d q = PointOn(*light.shape, HashUnit(key * 0x9E3779B9ull + 5), HashUnit(key ^ 0x5DEECE66Dull), &t);
  ++*rays;
  return light.radiance * std::min(Transfer(scene, *light.shape, origin, n, g, q, t) * light.shape->area, kPi);
}

Eigen::Vector3d SeenInAHole(const EmitterLight& light, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                            double before) {
  if (!light.in_a_hole || !light.shape) return Eigen::Vector3d::Zero();
  const EmitterShape& s = *light.shape;
  for (std::size_t t = 0; t < s.a.size(); ++t) {
    if (!(s.normal[t].cast<double>().dot(dir) < 0)) continue;  // (its back, or along it)
    // Moller-Trumbore.
    const Eigen::Vector3d a = s.a[t].cast<double>(), e1 = s.b[t].cast<double>() - a, e2 = s.c[t].cast<double>() - a;
    const Eigen::Vector3d p = dir.cross(e2);
    const double det = e1.dot(p);
    if (std::abs(det) < 1e-12) continue;
    const Eigen::Vector3d to = origin - a;
    const double u = to.dot(p) / det;
    if (u < 0 || u > 1) continue;
    const Eigen::Vector3d q = to.cross(e1);
    const double v = dir.dot(q) / det, d = e2.dot(q) / det;
    if (v < 0 || u + v > 1 || !(d > 0) || !(d < before - s.cell)) continue;
    return light.radiance;
  }
  return Eigen::Vector3d::Zero();
}

}  // namespace lp
