#include "reconstruction/depth_maps.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/parallel.h"

namespace lp {

namespace {
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
}

Camera ScaleIntrinsics(const Camera& k, int level) {
  Camera s = k;
  for (int l = 0; l < level; ++l) {
    s.width /= 2;
    s.height /= 2;
    s.fx *= 0.5;
    s.fy *= 0.5;
    // Pixel centres at integers: the 2x2 block (2x, 2x+1) has its centre at 2x + 0.5.
    s.cx = (s.cx - 0.5) * 0.5;
    s.cy = (s.cy - 0.5) * 0.5;
  }
  return s;
}

std::vector<float> NearestDepthAtLevel(const std::vector<float>& depth, int width, int height, int level) {
  const int f = 1 << level, w = width >> level, h = height >> level;
  std::vector<float> out(static_cast<std::size_t>(w) * h, 0.f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float nearest = std::numeric_limits<float>::max();
      bool all = true;
      for (int dy = 0; dy < f && all; ++dy)
        for (int dx = 0; dx < f && all; ++dx) {
          const float d = depth[static_cast<std::size_t>(y * f + dy) * width + x * f + dx];
          all = d > 0;
          nearest = std::min(nearest, d);
        }
      if (all) out[static_cast<std::size_t>(y) * w + x] = nearest;
    }
  return out;
}

std::vector<float> DepthToMetres(const DepthImage& depth, const PreprocessOptions& o) {
  std::vector<float> m(depth.data.size(), 0.f);
  for (std::size_t p = 0; p < m.size(); ++p) {
    const float z = depth.data[p] * 1e-3f;
    m[p] = z >= o.min_depth && z <= o.max_depth ? z : 0.f;
  }
  return m;
}

std::vector<float> BilateralFilter(const std::vector<float>& depth, int w, int h, const PreprocessOptions& o) {
  std::vector<float> out(depth.size(), 0.f);
  const int r = o.bilateral_radius;
  std::vector<float> spatial((2 * r + 1) * (2 * r + 1));
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx)
      spatial[(dy + r) * (2 * r + 1) + dx + r] = std::exp(-(dx * dx + dy * dy) / (2 * o.sigma_space * o.sigma_space));
  // Range weights by depth difference in steps of 0.5 mm up to the 3-sigma cut (a table:
  // 49 exp() per pixel cost as much as everything else in preprocessing).
  const float cut = 3 * o.sigma_depth, inv_step = 2000.f;
  std::vector<float> range(static_cast<std::size_t>(cut * inv_step) + 2);
  for (std::size_t i = 0; i < range.size(); ++i) {
    const float dz = i / inv_step;
    range[i] = std::exp(-dz * dz / (2 * o.sigma_depth * o.sigma_depth));
  }
  ParallelForChunks(0, static_cast<std::size_t>(h), 8, [&](std::size_t y0, std::size_t y1) {
    for (int y = static_cast<int>(y0); y < static_cast<int>(y1); ++y)
      for (int x = 0; x < w; ++x) {
        const float z = depth[static_cast<std::size_t>(y) * w + x];
        if (z <= 0) continue;
        float sum = 0, wsum = 0;
        for (int dy = std::max(-r, -y); dy <= std::min(r, h - 1 - y); ++dy) {
          const float* row = &depth[static_cast<std::size_t>(y + dy) * w];
          const float* sp = &spatial[(dy + r) * (2 * r + 1) + r];
          for (int dx = std::max(-r, -x); dx <= std::min(r, w - 1 - x); ++dx) {
            const float zn = row[x + dx], dz = zn - z;
            if (zn <= 0 || std::abs(dz) > cut) continue;
            const float wt = sp[dx] * range[static_cast<std::size_t>(std::abs(dz) * inv_step + 0.5f)];
            sum += wt * zn;
            wsum += wt;
          }
        }
        out[static_cast<std::size_t>(y) * w + x] = sum / wsum;
      }
  });
  return out;
}

void ComputeVertexNormalMaps(DepthLevel* l, int normal_radius) {
  const Camera& k = l->k;
  const int w = k.width, h = k.height;
  l->vertex.assign(l->depth.size(), Eigen::Vector3f::Constant(kNaN));
  l->normal.assign(l->depth.size(), Eigen::Vector3f::Constant(kNaN));
  const float ifx = static_cast<float>(1 / k.fx), ify = static_cast<float>(1 / k.fy);
  const float cx = static_cast<float>(k.cx), cy = static_cast<float>(k.cy);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t p = static_cast<std::size_t>(y) * w + x;
      const float z = l->depth[p];
      if (z > 0) l->vertex[p] = Eigen::Vector3f((x - cx) * z * ifx, (y - cy) * z * ify, z);
    }
  // Central differences over +-r pixels: a longer baseline than neighbours, so depth
  // noise tilts the normal less (at 3 m an Xtion's depth noise is ~1.5 pixel spacings).
  const int r = normal_radius;
  ParallelForChunks(0, static_cast<std::size_t>(h), 8, [&](std::size_t y0, std::size_t y1) {
    for (int y = static_cast<int>(y0); y < static_cast<int>(y1); ++y) {
      if (y < r || y + r >= h) continue;
      for (int x = r; x + r < w; ++x) {
        const std::size_t p = static_cast<std::size_t>(y) * w + x;
        const float z = l->depth[p];
        if (z <= 0) continue;
        // No normal across a depth discontinuity (more than 5 % + 1 cm apart).
        const float jump = (0.05f * z + 0.01f) * r;
        const std::size_t q[4] = {p - r, p + r, p - static_cast<std::size_t>(r) * w, p + static_cast<std::size_t>(r) * w};
        bool ok = true;
        for (std::size_t i : q) ok = ok && l->depth[i] > 0 && std::abs(l->depth[i] - z) <= jump;
        if (!ok) continue;
        const Eigen::Vector3f dx = l->vertex[q[1]] - l->vertex[q[0]], dy = l->vertex[q[3]] - l->vertex[q[2]];
        Eigen::Vector3f n(dx.y() * dy.z() - dx.z() * dy.y(), dx.z() * dy.x() - dx.x() * dy.z(),
                          dx.x() * dy.y() - dx.y() * dy.x());
        const float len = n.norm();
        if (!(len > 0)) continue;
        n /= len;
        if (n.dot(l->vertex[p]) > 0) n = -n;  // facing the camera
        l->normal[p] = n;
      }
    }
  });
}

std::vector<DepthLevel> PreprocessDepth(const DepthImage& depth, const Camera& k, const PreprocessOptions& o) {
  std::vector<DepthLevel> levels(static_cast<std::size_t>(std::max(1, o.levels)));
  const std::size_t first = static_cast<std::size_t>(std::clamp(o.first_level, 0, static_cast<int>(levels.size()) - 1));
  levels[0].k = k;
  levels[0].depth = DepthToMetres(depth, o);
  if (first == 0) levels[0].depth = BilateralFilter(levels[0].depth, depth.width, depth.height, o);
  for (std::size_t l = 1; l < levels.size(); ++l) {
    const DepthLevel& fine = levels[l - 1];
    DepthLevel& c = levels[l];
    c.k = ScaleIntrinsics(k, static_cast<int>(l));
    c.depth.assign(static_cast<std::size_t>(c.k.width) * c.k.height, 0.f);
    const int fw = fine.k.width;
    for (int y = 0; y < c.k.height; ++y)
      for (int x = 0; x < c.k.width; ++x) {
        float ref = 0, sum = 0;
        int n = 0;
        for (int dy = 0; dy < 2; ++dy)
          for (int dx = 0; dx < 2; ++dx) {
            const float z = fine.depth[static_cast<std::size_t>(2 * y + dy) * fw + 2 * x + dx];
            if (z <= 0) continue;
            if (ref == 0) ref = z;
            if (std::abs(z - ref) > 3 * o.sigma_depth) continue;
            sum += z;
            ++n;
          }
        c.depth[static_cast<std::size_t>(y) * c.k.width + x] = n > 0 ? sum / n : 0.f;
      }
    if (l == first) c.depth = BilateralFilter(c.depth, c.k.width, c.k.height, o);
  }
  // Levels finer than `first` keep their depth only (no maps: tracking does not use them).
  for (std::size_t l = 0; l < levels.size(); ++l) {
    if (l < first) continue;
    ComputeVertexNormalMaps(&levels[l], l == first ? o.normal_radius : 1);
  }
  return levels;
}

}  // namespace lp
