// Mesh extraction from the sparse TSDF by marching cubes. PCL's surface module provides
// the case tables (edgeTable, triTable: Lorensen & Cline / Bourke numbering); the sparse
// traversal, vertex sharing and colour are here. The only file that includes PCL's
// marching cubes header.
#include <pcl/surface/marching_cubes.h>

#include <cmath>
#include <unordered_map>

#include "common/parallel.h"
#include "reconstruction/volume_internal.h"

namespace lp {

namespace {

// Corner i of a cube in PCL's numbering, as an offset from its lower corner.
constexpr int kCorner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1}, {0, 1, 0}, {1, 1, 0}, {1, 1, 1}, {0, 1, 1}};
// Edge e joins corners kEdge[e][0] and kEdge[e][1].
constexpr int kEdge[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6}, {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};

/// An edge of the voxel grid: its lower end (20 bits per coordinate) and axis.
std::uint64_t EdgeKey(const int a[3], const int b[3]) {
  const int lo[3] = {std::min(a[0], b[0]), std::min(a[1], b[1]), std::min(a[2], b[2])};
  const int axis = a[0] != b[0] ? 0 : a[1] != b[1] ? 1 : 2;
  constexpr std::int64_t off = 1 << 19;
  const std::uint64_t packed = (static_cast<std::uint64_t>(lo[0] + off) << 40) |
                               (static_cast<std::uint64_t>(lo[1] + off) << 20) | static_cast<std::uint64_t>(lo[2] + off);
  return packed << 2 | static_cast<std::uint64_t>(axis);
}

struct BlockPart {
  std::vector<std::uint64_t> triangle_edges;  // 3 edge keys per triangle
  std::vector<std::pair<std::uint64_t, std::pair<Eigen::Vector3f, Eigen::Vector3f>>> vertices;  // key, position, colour
};

}  // namespace

Mesh TsdfVolume::ExtractMesh(float min_weight) const {
  const VolumeStore& st = impl_->store;
  const float voxel = st.voxel;
  std::vector<BlockPart> parts(st.blocks.size());
  ParallelForChunks(0, st.blocks.size(), 8, [&](std::size_t b0, std::size_t b1) {
    for (std::size_t b = b0; b < b1; ++b) {
      BlockPart& part = parts[b];
      const Eigen::Vector3i origin = st.coords[b] * kBlockSide;
      for (int lz = 0; lz < kBlockSide; ++lz)
        for (int ly = 0; ly < kBlockSide; ++ly)
          for (int lx = 0; lx < kBlockSide; ++lx) {
            const int g[3] = {origin.x() + lx, origin.y() + ly, origin.z() + lz};
            const Voxel* c[8];
            const VoxelColor* cc[8];
            if (!st.Cell(g[0], g[1], g[2], c, nullptr, cc)) continue;  // Cell's order: (c&1, c>>1&1, c>>2)
            const Voxel* v[8];
            const VoxelColor* vc[8];
            int corner[8][3];
            int cube = 0;
            bool heavy = true;
            for (int i = 0; i < 8; ++i) {
              const int* o = kCorner[i];
              v[i] = c[o[0] | o[1] << 1 | o[2] << 2];
              vc[i] = cc[o[0] | o[1] << 1 | o[2] << 2];
              for (int a = 0; a < 3; ++a) corner[i][a] = g[a] + o[a];
              heavy = heavy && v[i]->weight >= min_weight;
              if (v[i]->sdf_q < 0) cube |= 1 << i;
            }
            if (!heavy || pcl::edgeTable[cube] == 0) continue;
            std::uint64_t keys[12];
            for (int e = 0; e < 12; ++e) {
              if (!(pcl::edgeTable[cube] & (1 << e))) continue;
              const int a = kEdge[e][0], bb = kEdge[e][1];
              const float sa = v[a]->sdf(), sb = v[bb]->sdf();
              const float f = sa / (sa - sb);
              const Eigen::Vector3f pa(corner[a][0], corner[a][1], corner[a][2]);
              const Eigen::Vector3f pb(corner[bb][0], corner[bb][1], corner[bb][2]);
              const Eigen::Vector3f ca = vc[a]->rgb(), cb = vc[bb]->rgb();
              Eigen::Vector3f col = Eigen::Vector3f::Constant(0.5f);  // never seen in colour
              if (vc[a]->weight > 0 && vc[bb]->weight > 0) col = ca + f * (cb - ca);
              else if (vc[a]->weight > 0) col = ca;
              else if (vc[bb]->weight > 0) col = cb;
              keys[e] = EdgeKey(corner[a], corner[bb]);
              part.vertices.push_back({keys[e], {(pa + f * (pb - pa)) * voxel, col}});
            }
            // With bits set for negative (behind-surface) corners, the table's winding faces
            // free space (checked on a sphere in reconstruction_test).
            for (int i = 0; pcl::triTable[cube][i] != -1; ++i) part.triangle_edges.push_back(keys[pcl::triTable[cube][i]]);
          }
    }
  });
  Mesh mesh;
  std::unordered_map<std::uint64_t, int> index;
  std::size_t nv = 0;
  for (const BlockPart& p : parts) nv += p.vertices.size();
  index.reserve(nv);
  for (const BlockPart& p : parts)
    for (const auto& [key, pc] : p.vertices)
      if (index.emplace(key, static_cast<int>(mesh.positions.size())).second) {
        mesh.positions.push_back(pc.first);
        mesh.albedo.push_back(pc.second.cwiseMax(0.f).cwiseMin(1.f));
      }
  for (const BlockPart& p : parts)
    for (std::size_t i = 0; i + 2 < p.triangle_edges.size(); i += 3) {
      const Eigen::Vector3i t(index.at(p.triangle_edges[i]), index.at(p.triangle_edges[i + 1]),
                              index.at(p.triangle_edges[i + 2]));
      if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
      mesh.triangles.push_back(t);
    }
  ComputeVertexNormals(&mesh);
  return mesh;
}

}  // namespace lp
