#pragma once
/// Inside the TSDF volume (shared by tsdf_volume.cpp and marching_cubes.cpp only): the
/// voxel blocks, the open-addressing hash from block coordinates to blocks, and voxel
/// lookups across block borders.

#include <climits>
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "common/rng.h"
#include "reconstruction/tsdf_volume.h"

namespace lp {

struct VoxelBlock {
  Voxel v[kBlockVoxels];       ///< what raycasting reads, packed together
  VoxelColor c[kBlockVoxels];  ///< same order
};

/// Where the voxel blocks live: chunks of 4 MiB aligned to 2 MiB, offered to the kernel
/// as transparent huge pages. A ray or a fusion touches blocks scattered over tens of MiB;
/// one block each from the heap put nearly every step on a new 4 KiB page (a TLB miss).
class BlockArena {
 public:
  BlockArena() = default;
  BlockArena(const BlockArena&) = delete;
  BlockArena& operator=(const BlockArena&) = delete;
  BlockArena(BlockArena&&) noexcept = default;
  BlockArena& operator=(BlockArena&&) noexcept = default;
  /// A new block, every voxel unobserved.
  VoxelBlock* New();
  std::size_t Bytes() const { return chunks_.size() * kChunkBytes; }

 private:
  static constexpr std::size_t kChunkBytes = std::size_t{4} << 20;
  static constexpr std::size_t kPerChunk = kChunkBytes / sizeof(VoxelBlock);
  struct Free {
    void operator()(VoxelBlock* p) const;
  };
  std::vector<std::unique_ptr<VoxelBlock, Free>> chunks_;
  std::size_t used_ = kPerChunk;  ///< blocks handed out from the last chunk
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
  std::size_t Bytes() const { return slots_.size() * sizeof(Slot); }

 private:
  static constexpr std::uint64_t kEmpty = ~0ull;
  void Rehash(std::size_t capacity);
  struct Slot {  ///< key and value side by side: one cache line per probe
    std::uint64_t key = kEmpty;
    int value = -1;
  };
  std::vector<Slot> slots_;
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
  BlockArena arena;
  std::vector<VoxelBlock*> blocks;  ///< in arena
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

// The lookups every ray step and voxel makes, inline.

inline std::uint64_t BlockHash::Key(int bx, int by, int bz) {
  constexpr std::int64_t off = 1 << 20;
  return (static_cast<std::uint64_t>(bx + off) << 42) | (static_cast<std::uint64_t>(by + off) << 21) |
         static_cast<std::uint64_t>(bz + off);
}

inline int BlockHash::Find(std::uint64_t key) const {
  for (std::size_t i = SplitMix64(key) & mask_;; i = (i + 1) & mask_) {
    if (slots_[i].key == key) return slots_[i].value;
    if (slots_[i].key == kEmpty) return -1;
  }
}

inline int VolumeStore::FindBlock(int bx, int by, int bz, BlockCache* cache) const {
  if (!cache) return hash.Find(BlockHash::Key(bx, by, bz));
  if (cache->bx != bx || cache->by != by || cache->bz != bz) {
    *cache = {bx, by, bz, hash.Find(BlockHash::Key(bx, by, bz))};
  }
  return cache->index;
}

inline const Voxel* VolumeStore::VoxelAt(int ix, int iy, int iz, BlockCache* cache) const {
  const int b = FindBlock(ix >> kBlockShift, iy >> kBlockShift, iz >> kBlockShift, cache);
  if (b < 0) return nullptr;
  return &blocks[b]->v[LocalIndex(ix & kBlockMask, iy & kBlockMask, iz & kBlockMask)];
}


}  // namespace lp
