#pragma once
/// Inside the TSDF volume (shared by tsdf_volume.cpp and marching_cubes.cpp only): the
/// voxel blocks, the open-addressing hash from block coordinates to blocks, and voxel
/// lookups across block borders.

#include <climits>
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "reconstruction/tsdf_volume.h"

namespace lp {

struct VoxelBlock {
  Voxel v[kBlockVoxels];       ///< what raycasting reads, packed together
  VoxelColor c[kBlockVoxels];  ///< same order
};

/// Block coordinates (each within +-2^20) -> block index; linear probing, grows at half load.
class BlockHash {
 public:
  BlockHash();
  static std::uint64_t Key(int bx, int by, int bz);
  /// The index stored for `key`, or -1.
  int Find(std::uint64_t key) const;
  /// Stores `value` for a new key and returns it; for a present key returns its index.
  int Insert(std::uint64_t key, int value);
  std::size_t Bytes() const { return keys_.size() * (sizeof(std::uint64_t) + sizeof(int)); }

 private:
  static constexpr std::uint64_t kEmpty = ~0ull;
  void Rehash(std::size_t capacity);
  std::vector<std::uint64_t> keys_;
  std::vector<int> values_;
  std::size_t mask_ = 0, size_ = 0;
};

/// The last block looked up (rays and cells mostly stay in one block): saves the hash.
struct BlockCache {
  int bx = INT32_MIN, by = 0, bz = 0, index = -1;
};

/// Blocks, their coordinates and the hash. Voxel (ix, iy, iz) sits at (ix, iy, iz) * voxel
/// in the world and lives in block (ix >> kBlockShift, iy >> kBlockShift, iz >> kBlockShift).
struct VolumeStore {
  float voxel = 0.01f;
  BlockHash hash;
  std::vector<std::unique_ptr<VoxelBlock>> blocks;
  std::vector<Eigen::Vector3i> coords;  ///< block coordinates per block index

  static int LocalIndex(int lx, int ly, int lz) { return (lz * kBlockSide + ly) * kBlockSide + lx; }
  int FindBlock(int bx, int by, int bz, BlockCache* cache = nullptr) const;
  int AllocateBlock(int bx, int by, int bz);
  /// The voxel, or null where no block is allocated.
  const Voxel* VoxelAt(int ix, int iy, int iz, BlockCache* cache = nullptr) const;
  /// The 8 voxels of the cell with lower corner (ix, iy, iz), corner c at offset
  /// (c & 1, (c >> 1) & 1, c >> 2), and their colours if asked; false unless all are
  /// allocated and observed.
  bool Cell(int ix, int iy, int iz, const Voxel* out[8], BlockCache* cache = nullptr,
            const VoxelColor* colors[8] = nullptr) const;
  /// Trilinear signed distance (in truncation units) at world point p, with its gradient
  /// (per voxel) and colour (NaN when unobserved) if asked; false outside observed cells.
  bool Trilinear(const Eigen::Vector3f& p, float* sdf, Eigen::Vector3f* gradient, Eigen::Vector3f* color,
                 BlockCache* cache = nullptr) const;
};

struct TsdfVolume::Impl {
  TsdfOptions o;
  VolumeStore store;
  std::vector<int> stamp;  ///< per block: the last frame that touched it
  int frame = 0;
};

}  // namespace lp
