#pragma once
// The light kinds' tests' small scene: a 4 m plane of albedo 0.7 and a ball of radius 0.3,
// one view from (1.5, -1.5, 1.5), and its shading vertices (two bounces).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <vector>

#include "estimation/path_tracer.h"
#include "estimation/shading_vertices.h"
#include "scene/ray_tracer.h"
#include "tests/test_util.h"

namespace lp::test {

struct PlaneAndBall {
  /// A w x h view of hfov degrees; the vertices gathered at `spp` paths per pixel.
  PlaneAndBall(int w, int h, double hfov, int spp)
      : views{BlankView(LookAt({1.5, -1.5, 1.5}, {0, 0, 0.1}, w, h, hfov))} {
    options.spp = spp;
    options.bounces = 2;
    vertices = GatherShadingVertices(scene, views, options);
  }
  RayTracer scene{Merge(Plane(4, 0.7), Ball(0.3, 0.5))};
  std::vector<View> views;
  TracerOptions options;
  ShadingVertices vertices;
};

/// A light's column against the same sum made vertex by vertex: `vertex(k)` is vertex k's
/// share of its row (0 where it sees none of the light). The largest difference over the rows
/// and channels; `scale`, the largest entry of the sum.
inline double WorstColumnDifference(const ShadingVertices& v, const std::vector<float>& column,
                                    const std::function<Eigen::Vector3d(std::int64_t)>& vertex, double* scale) {
  double worst = 0;
  *scale = 0;
  for (std::size_t r = 0; r < v.rows(); ++r) {
    Eigen::Vector3d expect = Eigen::Vector3d::Zero();
    for (std::int64_t k = v.row_start[r]; k < v.row_start[r + 1]; ++k) expect += vertex(k);
    for (int c = 0; c < 3; ++c) {
      worst = std::max(worst, std::abs(expect[c] - column[3 * r + c]));
      *scale = std::max(*scale, std::abs(expect[c]));
    }
  }
  return worst;
}

}  // namespace lp::test
