#pragma once
// The light kinds' tests' small scene: a 4 m plane of albedo 0.7 and a ball of radius 0.3,
// one view from (1.5, -1.5, 1.5), and its shading vertices (two bounces).
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

}  // namespace lp::test
