#pragma once
/// The shadow rays of a chunk of shading vertices traced as one Embree stream
/// (RayTracer::OccludedMany), for the light kinds' columns: the same answers as each ray
/// traced alone, for less per ray.
#include <cstdint>
#include <vector>

#include "scene/ray_tracer.h"

namespace lp {

class ChunkVisibility {
 public:
  /// The shadow rays of each vertex k in [k0, k1): `rays(k, &out)` appends them and returns
  /// how many (0: it sees all of the light, as a vertex inside a lamp; -1: none, the light
  /// is behind it); all traced as one stream.
  template <class Rays>
  ChunkVisibility(const RayTracer& scene, std::int64_t k0, std::int64_t k1, Rays&& rays)
      : k0_(k0), first_(k1 - k0), count_(k1 - k0) {
    for (std::int64_t k = k0; k < k1; ++k) {
      first_[k - k0] = static_cast<int>(rays_.size());
      count_[k - k0] = rays(k, &rays_);
    }
    scene.OccludedMany(rays_, &blocked_);
  }
  /// Whether vertex k has the light in front of it (rays(k) was not -1).
  bool Faces(std::int64_t k) const { return count_[k - k0_] >= 0; }
  /// The share of vertex k's rays that nothing blocks (1 where it has none).
  double Seen(std::int64_t k) const {
    const int n = count_[k - k0_];
    if (n <= 0) return 1.0;
    int seen = n;
    for (int i = 0; i < n; ++i) seen -= blocked_[first_[k - k0_] + i];
    return static_cast<double>(seen) / n;
  }

 private:
  std::int64_t k0_;
  std::vector<int> first_, count_;
  std::vector<RayTracer::ShadowRay> rays_;
  std::vector<std::uint8_t> blocked_;
};

}  // namespace lp
