#pragma once
/// Ray queries against the scene mesh. Embree 3 stays inside ray_tracer.cpp
/// (the one file that would absorb the Embree 3 -> 4 API change).
#include <memory>

#include <cstdint>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "scene/mesh.h"

namespace lp {

/// A shading point on the mesh.
struct SurfacePoint {
  Eigen::Vector3d position;   ///< world, metres
  Eigen::Vector3d geometric;  ///< unit geometric normal, facing the incoming ray
  Eigen::Vector3d shading;    ///< unit interpolated normal, same side as `geometric`
  Eigen::Vector3d albedo;     ///< linear RGB, interpolated
  double distance = 0;        ///< along the ray
  int triangle = -1;
};

class RayTracer {
 public:
  /// Builds the BVH over a sanitized mesh (see SanitizeMesh); keeps a copy of it.
  explicit RayTracer(Mesh mesh);
  /// ... without the triangles where `open` is 1 (an opening: rays pass through them); the
  /// others keep their indices (SurfacePoint::triangle, mesh()).
  RayTracer(Mesh mesh, const std::vector<std::uint8_t>& open);
  ~RayTracer();
  RayTracer(const RayTracer&) = delete;
  RayTracer& operator=(const RayTracer&) = delete;

  /// Closest hit along origin + t*dir, t in (epsilon, tmax); `dir` unit length.
  bool Intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, SurfacePoint* hit,
                 double tmax = 1e30) const;
  /// True if anything lies along origin + t*dir, t in (epsilon, tmax).
  bool Occluded(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double tmax = 1e30) const;
  /// A shadow ray for OccludedMany: from `origin` along unit `dir`, t in (epsilon, tmax).
  struct ShadowRay {
    Eigen::Vector3f origin, dir;
    float tmax;
  };
  /// Occluded for each of `rays` (blocked[i] = 1 where anything lies along it), traced as one
  /// stream: the same answers as Occluded ray by ray, for less per ray where they are many.
  void OccludedMany(const std::vector<ShadowRay>& rays, std::vector<std::uint8_t>* blocked) const;
  /// Embree alone, for the tracer's throughput benchmark (`lightprobe bench --parts rays`):
  /// rtcIntersect1 on each ray (origin, unit direction) over this BVH, on all cores, with no
  /// hit record made; returns how many hit.
  std::int64_t CountHits(const std::vector<std::pair<Eigen::Vector3f, Eigen::Vector3f>>& rays) const;

  /// Ray offset used to leave a surface, proportional to the scene size.
  double epsilon() const { return epsilon_; }
  const Mesh& mesh() const { return mesh_; }
  /// Per triangle: 1 where it is left out of the BVH (empty: none is).
  const std::vector<std::uint8_t>& open() const { return open_; }
  /// Centre and radius of the bounding sphere of the mesh's bounding box.
  Eigen::Vector3d center() const { return center_; }
  double radius() const { return radius_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  Mesh mesh_;
  std::vector<std::uint8_t> open_;
  std::vector<int> triangle_of_;  ///< per BVH primitive: its triangle (empty: the same)
  double epsilon_ = 1e-4;
  Eigen::Vector3d center_;
  double radius_ = 1;
};

}  // namespace lp
