#include "estimation/portal.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "estimation/envmap.h"
#include "estimation/lights/emitter_light.h"
#include "estimation/seen_windows.h"

namespace lp {

double Portal::Crossing(const Eigen::Vector3d& origin, const Eigen::Vector3d& w, double* cos) const {
  const Eigen::Vector3d n = axis_u.cross(axis_v);
  const double along = w.dot(n);
  if (std::abs(along) < 1e-9) return 0;
  const double t = (centre - origin).dot(n) / along;
  if (!(t > 0)) return 0;
  const Eigen::Vector3d p = origin + t * w - centre;
  if (std::abs(p.dot(axis_u)) > half_u || std::abs(p.dot(axis_v)) > half_v) return 0;
  *cos = std::abs(along);
  return t;
}

Portal PortalAround(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& point,
                    const Eigen::Vector3d& normal, const Eigen::Vector3d& along) {
  Portal p;
  const Eigen::Vector3d n = normal.normalized();
  Eigen::Vector3d u = along - along.dot(n) * n;
  if (u.norm() < 1e-6) u = n.unitOrthogonal();
  p.axis_u = u.normalized();
  p.axis_v = n.cross(p.axis_u);
  double lo_u = 0, hi_u = 0, lo_v = 0, hi_v = 0;
  for (std::size_t k = 0; k < points.size(); ++k) {
    const Eigen::Vector3d d = points[k] - point;
    const double a = d.dot(p.axis_u), b = d.dot(p.axis_v);
    lo_u = k ? std::min(lo_u, a) : a, hi_u = k ? std::max(hi_u, a) : a;
    lo_v = k ? std::min(lo_v, b) : b, hi_v = k ? std::max(hi_v, b) : b;
  }
  p.centre = point + 0.5 * (lo_u + hi_u) * p.axis_u + 0.5 * (lo_v + hi_v) * p.axis_v;
  p.half_u = 0.5 * (hi_u - lo_u);
  p.half_v = 0.5 * (hi_v - lo_v);
  return p;
}

Portal PortalOf(const EmitterShape& shape, const Eigen::Vector3d& up) {
  std::vector<Eigen::Vector3d> corners;
  for (std::size_t t = 0; t < shape.a.size(); ++t)
    corners.insert(corners.end(), {shape.a[t].cast<double>(), shape.b[t].cast<double>(), shape.c[t].cast<double>()});
  const Eigen::Vector3d normal = FacingSum(shape).normalized();
  return PortalAround(corners, Centroid(shape), normal, up.cross(normal));
}

bool PortalOf(const SeenWindow& w, const Eigen::Vector3d& up, Portal* out) {
  if (w.outline.empty()) return false;
  *out = PortalAround(w.outline, w.centre, w.normal, up.cross(w.normal));
  return true;
}

Eigen::Vector3d PowerThrough(const Portal& window, const Eigen::Vector3d& inward, const EnvMap& env,
                             const std::vector<double>& rgb) {
  LP_CHECK(rgb.size() == 3 * static_cast<std::size_t>(env.size()), "PowerThrough: the map's size");
  constexpr int kSide = 8;
  const Eigen::Vector3d n = inward.normalized();
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int j = 0; j < env.size(); ++j) {
    const Eigen::Vector3d L(rgb[3 * j], rgb[3 * j + 1], rgb[3 * j + 2]);
    if (L.isZero()) continue;
    double cos = 0;
    for (int a = 0; a < kSide; ++a)
      for (int b = 0; b < kSide; ++b) cos += std::max(0.0, -env.SampleInCell(j, (a + 0.5) / kSide, (b + 0.5) / kSide).dot(n));
    sum += L * env.solid_angle(j) * cos / (kSide * kSide);
  }
  return window.Area() * sum;
}

}  // namespace lp
