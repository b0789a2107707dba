#include "reconstruction/tsdf_volume.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/error.h"
#include "common/parallel.h"
#include "common/rng.h"
#include "reconstruction/volume_internal.h"

namespace lp {

namespace {
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
}  // namespace

// ---- BlockHash ----------------------------------------------------------------------

BlockHash::BlockHash() { Rehash(1024); }

std::uint64_t BlockHash::Key(int bx, int by, int bz) {
  constexpr std::int64_t off = 1 << 20;
  return (static_cast<std::uint64_t>(bx + off) << 42) | (static_cast<std::uint64_t>(by + off) << 21) |
         static_cast<std::uint64_t>(bz + off);
}

int BlockHash::Find(std::uint64_t key) const {
  for (std::size_t i = SplitMix64(key) & mask_;; i = (i + 1) & mask_) {
    if (keys_[i] == key) return values_[i];
    if (keys_[i] == kEmpty) return -1;
  }
}

int BlockHash::Insert(std::uint64_t key, int value) {
  if (2 * (size_ + 1) > keys_.size()) Rehash(2 * keys_.size());
  for (std::size_t i = SplitMix64(key) & mask_;; i = (i + 1) & mask_) {
    if (keys_[i] == key) return values_[i];
    if (keys_[i] == kEmpty) {
      keys_[i] = key;
      values_[i] = value;
      ++size_;
      return value;
    }
  }
}

void BlockHash::Rehash(std::size_t capacity) {
  std::vector<std::uint64_t> old_keys = std::move(keys_);
  std::vector<int> old_values = std::move(values_);
  keys_.assign(capacity, kEmpty);
  values_.assign(capacity, -1);
  mask_ = capacity - 1;
  size_ = 0;
  for (std::size_t i = 0; i < old_keys.size(); ++i)
    if (old_keys[i] != kEmpty) Insert(old_keys[i], old_values[i]);
}

// ---- VolumeStore ---------------------------------------------------------------------

int VolumeStore::FindBlock(int bx, int by, int bz, BlockCache* cache) const {
  if (!cache) return hash.Find(BlockHash::Key(bx, by, bz));
  if (cache->bx != bx || cache->by != by || cache->bz != bz) {
    *cache = {bx, by, bz, hash.Find(BlockHash::Key(bx, by, bz))};
  }
  return cache->index;
}

int VolumeStore::AllocateBlock(int bx, int by, int bz) {
  const int next = static_cast<int>(blocks.size());
  const int index = hash.Insert(BlockHash::Key(bx, by, bz), next);
  if (index == next) {
    blocks.push_back(std::make_unique<VoxelBlock>());
    coords.emplace_back(bx, by, bz);
  }
  return index;
}

const Voxel* VolumeStore::VoxelAt(int ix, int iy, int iz, BlockCache* cache) const {
  const int b = FindBlock(ix >> kBlockShift, iy >> kBlockShift, iz >> kBlockShift, cache);
  if (b < 0) return nullptr;
  return &blocks[b]->v[LocalIndex(ix & kBlockMask, iy & kBlockMask, iz & kBlockMask)];
}

bool VolumeStore::Cell(int ix, int iy, int iz, const Voxel* out[8], BlockCache* cache,
                       const VoxelColor* colors[8]) const {
  const int lx = ix & kBlockMask, ly = iy & kBlockMask, lz = iz & kBlockMask;
  if (lx < kBlockMask && ly < kBlockMask && lz < kBlockMask) {  // fast path: the whole cell in one block
    const int b = FindBlock(ix >> kBlockShift, iy >> kBlockShift, iz >> kBlockShift, cache);
    if (b < 0) return false;
    const VoxelBlock& blk = *blocks[b];
    for (int c = 0; c < 8; ++c) {
      const int i = LocalIndex(lx + (c & 1), ly + ((c >> 1) & 1), lz + (c >> 2));
      out[c] = &blk.v[i];
      if (colors) colors[c] = &blk.c[i];
    }
  } else {
    for (int c = 0; c < 8; ++c) {
      const int x = ix + (c & 1), y = iy + ((c >> 1) & 1), z = iz + (c >> 2);
      const int b = FindBlock(x >> kBlockShift, y >> kBlockShift, z >> kBlockShift, cache);
      if (b < 0) return false;
      const int i = LocalIndex(x & kBlockMask, y & kBlockMask, z & kBlockMask);
      out[c] = &blocks[b]->v[i];
      if (colors) colors[c] = &blocks[b]->c[i];
    }
  }
  for (int c = 0; c < 8; ++c)
    if (out[c]->weight == 0) return false;
  return true;
}

bool VolumeStore::Trilinear(const Eigen::Vector3f& p, float* sdf, Eigen::Vector3f* gradient, Eigen::Vector3f* color,
                            BlockCache* cache) const {
  const Eigen::Vector3f g = p / voxel;
  const int ix = static_cast<int>(std::floor(g.x())), iy = static_cast<int>(std::floor(g.y())),
            iz = static_cast<int>(std::floor(g.z()));
  const Voxel* c[8];
  const VoxelColor* cc[8];
  if (!Cell(ix, iy, iz, c, cache, color ? cc : nullptr)) return false;
  const float fx = g.x() - ix, fy = g.y() - iy, fz = g.z() - iz;
  float s[8];
  for (int k = 0; k < 8; ++k) s[k] = c[k]->sdf();
  // Corner c sits at (c & 1, (c >> 1) & 1, c >> 2).
  const float x00 = s[0] + fx * (s[1] - s[0]), x10 = s[2] + fx * (s[3] - s[2]);
  const float x01 = s[4] + fx * (s[5] - s[4]), x11 = s[6] + fx * (s[7] - s[6]);
  const float y0 = x00 + fy * (x10 - x00), y1 = x01 + fy * (x11 - x01);
  *sdf = y0 + fz * (y1 - y0);
  if (gradient) {
    const float dx0 = (1 - fy) * (s[1] - s[0]) + fy * (s[3] - s[2]);
    const float dx1 = (1 - fy) * (s[5] - s[4]) + fy * (s[7] - s[6]);
    const float dy0 = (1 - fx) * (s[2] - s[0]) + fx * (s[3] - s[1]);
    const float dy1 = (1 - fx) * (s[6] - s[4]) + fx * (s[7] - s[5]);
    *gradient = Eigen::Vector3f((1 - fz) * dx0 + fz * dx1, (1 - fz) * dy0 + fz * dy1, y1 - y0);
  }
  if (color) {
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    float wsum = 0;
    for (int k = 0; k < 8; ++k) {
      if (cc[k]->weight == 0) continue;
      const float w = ((k & 1) ? fx : 1 - fx) * (((k >> 1) & 1) ? fy : 1 - fy) * ((k >> 2) ? fz : 1 - fz);
      sum += w * cc[k]->rgb();
      wsum += w;
    }
    *color = wsum > 0 ? Eigen::Vector3f(sum / wsum) : Eigen::Vector3f::Constant(kNaN);
  }
  return true;
}

// ---- TsdfVolume ----------------------------------------------------------------------

TsdfVolume::TsdfVolume(const TsdfOptions& o) : impl_(std::make_unique<Impl>()) {
  impl_->o = o;
  impl_->store.voxel = o.voxel;
}
TsdfVolume::~TsdfVolume() = default;
TsdfVolume::TsdfVolume(TsdfVolume&&) noexcept = default;
TsdfVolume& TsdfVolume::operator=(TsdfVolume&&) noexcept = default;

TsdfVolume TsdfVolume::Clone() const {
  TsdfVolume copy(impl_->o);
  Impl& c = *copy.impl_;
  const Impl& m = *impl_;
  c.store.voxel = m.store.voxel;
  c.store.hash = m.store.hash;
  c.store.coords = m.store.coords;
  c.store.blocks.reserve(m.store.blocks.size());
  for (const auto& b : m.store.blocks) c.store.blocks.push_back(std::make_unique<VoxelBlock>(*b));
  c.stamp = m.stamp;
  c.frame = m.frame;
  return copy;
}

const TsdfOptions& TsdfVolume::options() const { return impl_->o; }
std::size_t TsdfVolume::BlockCount() const { return impl_->store.blocks.size(); }
std::size_t TsdfVolume::MemoryBytes() const {
  return impl_->store.blocks.size() * (sizeof(VoxelBlock) + sizeof(Eigen::Vector3i) + sizeof(int)) +
         impl_->store.hash.Bytes();
}

namespace {

/// A depth camera's pinhole in floats, for the per-pixel and per-voxel loops.
struct Pinhole {
  float fx, fy, cx, cy;
  int w, h;
  explicit Pinhole(const Camera& k)
      : fx(static_cast<float>(k.fx)), fy(static_cast<float>(k.fy)), cx(static_cast<float>(k.cx)),
        cy(static_cast<float>(k.cy)), w(k.width), h(k.height) {}
  Eigen::Vector3f Ray(int x, int y) const { return {(x - cx) / fx, (y - cy) / fy, 1.f}; }
};

/// Blocks within the truncation band of each measurement (every second pixel: a block
/// spans many pixels at any useful depth), per row pair, in ray order.
std::vector<std::vector<Eigen::Vector3i>> BandBlocks(const std::vector<float>& depth, const Pinhole& k,
                                                      const Eigen::Matrix3f& R, const Eigen::Vector3f& t, float trunc,
                                                      float block) {
  const std::size_t rows = static_cast<std::size_t>((k.h + 1) / 2);
  std::vector<std::vector<Eigen::Vector3i>> found(rows);
  ParallelForChunks(0, rows, 8, [&](std::size_t r0, std::size_t r1) {
    for (std::size_t r = r0; r < r1; ++r) {
      const int y = static_cast<int>(2 * r);
      Eigen::Vector3i last(INT32_MIN, 0, 0);
      for (int x = 0; x < k.w; x += 2) {
        const float z = depth[static_cast<std::size_t>(y) * k.w + x];
        if (z <= 0) continue;
        const Eigen::Vector3f ray = k.Ray(x, y);
        const float len = ray.norm(), dz = trunc / len;  // the band is +-trunc along the ray
        const int steps = static_cast<int>(std::ceil(2 * trunc / (0.5f * block))) + 1;
        for (int s = 0; s <= steps; ++s) {
          const float zs = z - dz + (2 * dz) * s / steps;
          if (zs <= 0) continue;
          const Eigen::Vector3f p = R * (ray * zs) + t;
          const Eigen::Vector3i b(static_cast<int>(std::floor(p.x() / block)),
                                  static_cast<int>(std::floor(p.y() / block)),
                                  static_cast<int>(std::floor(p.z() / block)));
          if (b != last) found[r].push_back(b);
          last = b;
        }
      }
    }
  });
  return found;
}

/// Unregistered frames: what the colour camera sees is not what the depth camera sees. The
/// depth map's points splatted into the colour camera (3x3, nearest kept) say how far its
/// nearest surface is per colour pixel; a voxel more than a truncation behind it is hidden
/// from the colour camera and takes no colour (else it took the colour in front of it).
std::vector<float> ColorCameraDepth(const std::vector<float>& depth, const Pinhole& k, const Pinhole& ck,
                                    const Eigen::Matrix3f& Rcd, const Eigen::Vector3f& tcd, int cw, int ch) {
  std::vector<float> color_z(static_cast<std::size_t>(cw) * ch, std::numeric_limits<float>::infinity());
  for (int y = 0; y < k.h; ++y)
    for (int x = 0; x < k.w; ++x) {
      const float z = depth[static_cast<std::size_t>(y) * k.w + x];
      if (z <= 0) continue;
      const Eigen::Vector3f q = Rcd * (k.Ray(x, y) * z) + tcd;
      if (q.z() <= 0) continue;
      const int u = static_cast<int>(std::lround(ck.fx * q.x() / q.z() + ck.cx));
      const int v = static_cast<int>(std::lround(ck.fy * q.y() / q.z() + ck.cy));
      for (int dv = -1; dv <= 1; ++dv)
        for (int du = -1; du <= 1; ++du) {
          if (u + du < 0 || v + dv < 0 || u + du >= cw || v + dv >= ch) continue;
          float& zb = color_z[static_cast<std::size_t>(v + dv) * cw + u + du];
          zb = std::min(zb, q.z());
        }
    }
  return color_z;
}

/// Step 2 of integration: every voxel of a touched block takes the projective signed
/// distance along its pixel's ray (a running average) and, near the surface, the colour.
struct VoxelUpdate {
  const std::vector<float>& depth;
  Pinhole k, ck;
  const ImageRGB* color;
  bool extrinsics;  ///< colour from another camera (Rcd, tcd)
  Eigen::Matrix3f Rt, Rcd;
  Eigen::Vector3f tc, tcd;
  float voxel, trunc;
  int max_w;
  std::vector<float> inv;         ///< 1 / (weight + 1): no division per voxel
  std::vector<float> lambda;      ///< per pixel: ray length per unit depth (no square root per voxel)
  std::vector<float> color_z;     ///< ColorCameraDepth, or empty

  VoxelUpdate(const std::vector<float>& depth_, const Camera& k_, const ImageRGB* color_, const Camera& color_k,
              const Eigen::Matrix4f& wfc, const Eigen::Matrix4d* color_from_depth, float voxel_, float trunc_,
              float max_weight)
      : depth(depth_), k(k_), ck(color_k), color(color_), extrinsics(color_from_depth != nullptr), voxel(voxel_),
        trunc(trunc_) {
    const Eigen::Matrix3f R = wfc.block<3, 3>(0, 0);
    Rt = R.transpose();
    tc = -Rt * wfc.block<3, 1>(0, 3);  // camera_from_world
    const Eigen::Matrix4f cfd = color_from_depth ? Eigen::Matrix4f(color_from_depth->cast<float>())
                                                 : Eigen::Matrix4f(Eigen::Matrix4f::Identity());
    Rcd = cfd.block<3, 3>(0, 0);
    tcd = cfd.block<3, 1>(0, 3);
    if (color && color_from_depth) color_z = ColorCameraDepth(depth, k, ck, Rcd, tcd, color->width, color->height);
    max_w = static_cast<int>(std::clamp(max_weight, 1.f, 65535.f));
    inv.resize(static_cast<std::size_t>(max_w) + 1);
    for (std::size_t i = 0; i < inv.size(); ++i) inv[i] = 1.f / (i + 1);
    lambda.resize(static_cast<std::size_t>(k.w) * k.h);
    for (int y = 0; y < k.h; ++y)
      for (int x = 0; x < k.w; ++x)
        lambda[static_cast<std::size_t>(y) * k.w + x] =
            std::sqrt(1 + ((x - k.cx) / k.fx) * ((x - k.cx) / k.fx) + ((y - k.cy) / k.fy) * ((y - k.cy) / k.fy));
  }

  void Block(VoxelBlock& blk, const Eigen::Vector3i& origin) const {
    for (int lz = 0; lz < kBlockSide; ++lz)
      for (int ly = 0; ly < kBlockSide; ++ly) {
        const Eigen::Vector3f row_start = Rt * (Eigen::Vector3f(origin.x(), origin.y() + ly, origin.z() + lz) * voxel) + tc;
        const Eigen::Vector3f step = Rt.col(0) * voxel;
        for (int lx = 0; lx < kBlockSide; ++lx)
          UpdateVoxel(blk, VolumeStore::LocalIndex(lx, ly, lz), row_start + step * static_cast<float>(lx));
      }
  }

  void UpdateVoxel(VoxelBlock& blk, int li, const Eigen::Vector3f& pc) const {
    if (pc.z() <= 0) return;
    const float iz = 1.f / pc.z();
    // +0.5 and truncation round to nearest for the in-image (non-negative) range.
    const float uf = k.fx * pc.x() * iz + k.cx + 0.5f, vf = k.fy * pc.y() * iz + k.cy + 0.5f;
    if (!(uf >= 0 && vf >= 0 && uf < k.w && vf < k.h)) return;  // NaN fails too
    const std::size_t pix = static_cast<std::size_t>(static_cast<int>(vf)) * k.w + static_cast<int>(uf);
    const float d = depth[pix];
    if (d <= 0) return;
    const float sdf = (d - pc.z()) * lambda[pix];
    if (sdf < -trunc) return;
    const float tsdf = std::min(1.f, sdf / trunc);
    Voxel& vx = blk.v[li];
    vx.set_sdf((vx.sdf() * vx.weight + tsdf) * inv[vx.weight]);
    vx.weight = static_cast<std::uint16_t>(std::min<int>(vx.weight + 1, max_w));
    if (!color || std::abs(sdf) > 0.5f * trunc) return;
    Color(blk.c[li], extrinsics ? Eigen::Vector3f(Rcd * pc + tcd) : pc);
  }

  void Color(VoxelColor& vc, const Eigen::Vector3f& pcol) const {
    if (pcol.z() <= 0) return;
    const int cu = static_cast<int>(std::lround(ck.fx * pcol.x() / pcol.z() + ck.cx));
    const int cv = static_cast<int>(std::lround(ck.fy * pcol.y() / pcol.z() + ck.cy));
    if (cu < 0 || cv < 0 || cu >= color->width || cv >= color->height) return;
    if (!color_z.empty() && pcol.z() > color_z[static_cast<std::size_t>(cv) * color->width + cu] + trunc) return;
    const float* c = color->at(cu, cv);
    if (!(std::isfinite(c[0]) && std::isfinite(c[1]) && std::isfinite(c[2]))) return;
    const float cw = vc.weight;
    auto mix = [&](std::uint16_t old, float value) {
      const float v = (old * (1.f / 65535.f) * cw + std::clamp(value, 0.f, 1.f)) / (cw + 1);
      return static_cast<std::uint16_t>(v * 65535.f + 0.5f);
    };
    vc.r = mix(vc.r, c[0]);
    vc.g = mix(vc.g, c[1]);
    vc.b = mix(vc.b, c[2]);
    vc.weight = static_cast<std::uint16_t>(std::min<int>(vc.weight + 1, max_w));
  }
};

}  // namespace

std::size_t TsdfVolume::Integrate(const std::vector<float>& depth, const Camera& k, const ImageRGB* color,
                                  const Camera& color_k, const Eigen::Matrix4d& world_from_camera,
                                  const Eigen::Matrix4d* color_from_depth) {
  Impl& m = *impl_;
  VolumeStore& st = m.store;
  const float voxel = m.o.voxel, trunc = m.o.truncation, block = voxel * kBlockSide;
  const Eigen::Matrix4f wfc = world_from_camera.cast<float>();

  // 1. The blocks within the band, allocated; each touched once.
  const auto found = BandBlocks(depth, Pinhole(k), wfc.block<3, 3>(0, 0), wfc.block<3, 1>(0, 3), trunc, block);
  ++m.frame;
  std::vector<int> touched;
  constexpr int kMaxBlock = 1 << 16;  // keys hold +-2^20; edge keys of the mesh +-2^19 voxels
  for (const auto& list : found)
    for (const Eigen::Vector3i& b : list) {
      if (b.cwiseAbs().maxCoeff() >= kMaxBlock) continue;  // kilometres away: not a room
      const int index = st.AllocateBlock(b.x(), b.y(), b.z());
      LP_CHECK(index >= 0, "block hash returned no index");
      if (static_cast<std::size_t>(index) >= m.stamp.size()) m.stamp.resize(st.blocks.size(), 0);
      if (m.stamp[index] == m.frame) continue;
      m.stamp[index] = m.frame;
      touched.push_back(index);
    }

  // 2. Every voxel of the touched blocks (projective signed distance along the ray).
  const VoxelUpdate update(depth, k, color, color_k, wfc, color_from_depth, voxel, trunc, m.o.max_weight);
  ParallelForChunks(0, touched.size(), 16, [&](std::size_t i0, std::size_t i1) {
    for (std::size_t i = i0; i < i1; ++i) update.Block(*st.blocks[touched[i]], st.coords[touched[i]] * kBlockSide);
  });
  return touched.size();
}

float TsdfVolume::SignedDistance(const Eigen::Vector3f& p) const {
  float s;
  if (!impl_->store.Trilinear(p, &s, nullptr, nullptr)) return kNaN;
  return s * impl_->o.truncation;
}

namespace {

constexpr int kTile = 8;
/// Rays stop this far from the camera (metres along its axis): twice a depth camera's
/// range. A volume with blocks far apart (a bad pose fused far away) would otherwise have
/// every ray march the whole way between them (a soak's reconstruction stalled for minutes
/// in one raycast).
constexpr float kMaxRayDepth = 10.0f;

/// Depth range per 8x8 tile of the image where a ray may meet the model.
struct TileRanges {
  int tw, th;
  std::vector<float> zmin, zmax;
  TileRanges(int w, int h)
      : tw((w + kTile - 1) / kTile), th((h + kTile - 1) / kTile),
        zmin(static_cast<std::size_t>(tw) * th, std::numeric_limits<float>::max()), zmax(zmin.size(), 0) {}
  std::size_t Tile(int x, int y) const { return static_cast<std::size_t>(y / kTile) * tw + x / kTile; }
};

/// From the allocated blocks' bounding spheres, so rays start near the model instead of
/// marching through empty space.
void AddBlockRanges(const VolumeStore& st, const Pinhole& k, const Eigen::Matrix3f& Rt, const Eigen::Vector3f& tc,
                    float block, TileRanges* r) {
  const float radius = 0.5f * std::sqrt(3.f) * block;
  for (std::size_t b = 0; b < st.coords.size(); ++b) {
    const Eigen::Vector3f centre = (st.coords[b].cast<float>() + Eigen::Vector3f::Constant(0.5f)) * block;
    const Eigen::Vector3f pc = Rt * centre + tc;
    if (pc.z() + radius < 0.05f) continue;
    const float z = std::max(pc.z(), 0.05f + radius);
    const float u = k.fx * pc.x() / z + k.cx, v = k.fy * pc.y() / z + k.cy;
    const float ru = k.fx * radius / (z - radius) + 1, rv = k.fy * radius / (z - radius) + 1;
    const int tx0 = std::max(0, static_cast<int>(std::floor((u - ru) / kTile)));
    const int tx1 = std::min(r->tw - 1, static_cast<int>(std::floor((u + ru) / kTile)));
    const int ty0 = std::max(0, static_cast<int>(std::floor((v - rv) / kTile)));
    const int ty1 = std::min(r->th - 1, static_cast<int>(std::floor((v + rv) / kTile)));
    for (int ty = ty0; ty <= ty1; ++ty)
      for (int tx = tx0; tx <= tx1; ++tx) {
        float& lo = r->zmin[static_cast<std::size_t>(ty) * r->tw + tx];
        float& hi = r->zmax[static_cast<std::size_t>(ty) * r->tw + tx];
        lo = std::min(lo, std::max(0.05f, pc.z() - radius));
        hi = std::max(hi, pc.z() + radius);
      }
  }
}

/// Tiles fully hit in the hint (the previous raycast there): its depth range, grown by
/// one tile each way (the view moved a little) and by the truncation plus 5 cm in depth.
void NarrowByHint(const TsdfVolume::Maps& hint, int w, int h, float trunc, TileRanges* r) {
  const int tw = r->tw, th = r->th;
  std::vector<float> lo(r->zmin.size(), std::numeric_limits<float>::max()), hi(r->zmin.size(), 0);
  std::vector<char> full(r->zmin.size(), 1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t tile = r->Tile(x, y);
      const float z = hint.depth[static_cast<std::size_t>(y) * w + x];
      if (z <= 0) {
        full[tile] = 0;
        continue;
      }
      lo[tile] = std::min(lo[tile], z);
      hi[tile] = std::max(hi[tile], z);
    }
  const float margin = trunc + 0.05f;
  for (int ty = 0; ty < th; ++ty)
    for (int tx = 0; tx < tw; ++tx) {
      float a = std::numeric_limits<float>::max(), b = 0;
      bool ok = true;
      for (int dy = -1; dy <= 1 && ok; ++dy)
        for (int dx = -1; dx <= 1 && ok; ++dx) {
          const int nx = std::clamp(tx + dx, 0, tw - 1), ny = std::clamp(ty + dy, 0, th - 1);
          const std::size_t n = static_cast<std::size_t>(ny) * tw + nx;
          ok = full[n] != 0;
          a = std::min(a, lo[n]);
          b = std::max(b, hi[n]);
        }
      if (!ok) continue;
      const std::size_t tile = static_cast<std::size_t>(ty) * tw + tx;
      r->zmin[tile] = std::max(r->zmin[tile], a - margin);
      r->zmax[tile] = std::min(r->zmax[tile], b + margin);
    }
}

/// One pixel's ray through the volume: the first zero crossing from the front.
struct RayMarch {
  const VolumeStore& st;
  Pinhole k;
  Eigen::Matrix3f R;
  Eigen::Vector3f t;
  float voxel, trunc;
  bool with_color;

  /// Distance along the unit ray `dir` from `t` where an unallocated block is left.
  float BlockExit(const Eigen::Vector3f& p, const Eigen::Vector3f& dir, int ix, int iy, int iz) const {
    float exit = std::numeric_limits<float>::max();
    for (int a = 0; a < 3; ++a) {
      if (dir[a] == 0) continue;
      const int b = ((a == 0 ? ix : a == 1 ? iy : iz) >> kBlockShift) + (dir[a] > 0 ? 1 : 0);
      // Voxel i covers [i - 0.5, i + 0.5) in voxel units (nearest voxel).
      const float boundary = (b * kBlockSide - 0.5f) * voxel;
      exit = std::min(exit, (boundary - p[a]) / dir[a]);
    }
    return exit;
  }

  /// The crossing between `a` (in front, value prev_s) and `b` (behind, value s), placed
  /// with trilinear values; writes the pixel when the gradient is usable.
  void Hit(float a, float b, float prev_s, float s, bool prev_precise, bool precise, const Eigen::Vector3f& dir,
           float len, std::size_t p_idx, BlockCache* cache, TsdfVolume::Maps* out) const {
    float fa = prev_s, fb = s;
    if (!prev_precise) st.Trilinear(t + dir * a, &fa, nullptr, nullptr, cache);
    if (!precise || !(fa > 0)) {
      fa = prev_s;
      fb = s;
    }
    if (b - a > voxel) {  // one regula falsi step on a long bracket
      const float m = a + (b - a) * fa / (fa - fb);
      float fm;
      if (st.Trilinear(t + dir * m, &fm, nullptr, nullptr, cache)) {
        if (fm > 0) {
          a = m;
          fa = fm;
        } else {
          b = m;
          fb = fm;
        }
      }
    }
    const float th = a + (b - a) * fa / (fa - fb);
    const Eigen::Vector3f hit = t + dir * th;
    float sh;
    Eigen::Vector3f grad, col;
    if (st.Trilinear(hit, &sh, &grad, with_color ? &col : nullptr, cache) && grad.norm() > 0) {
      out->vertex[p_idx] = hit;
      out->normal[p_idx] = grad.normalized();
      out->depth[p_idx] = th / len;
      if (with_color) out->color[p_idx] = col;
    }
  }

  void Cast(int x, int y, float zmin, float zmax, TsdfVolume::Maps* out) const {
    const Eigen::Vector3f ray_c((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1.f);
    const float len = ray_c.norm();
    const Eigen::Vector3f dir = R * (ray_c / len);
    // Distance along the ray from depth along the axis: t = z * len.
    float tr = zmin * len;
    const float t_end = zmax * len;
    float prev_t = -1, prev_s = kNaN;
    bool prev_precise = false;
    BlockCache cache;
    while (tr <= t_end) {
      const Eigen::Vector3f p = t + dir * tr;
      const Eigen::Vector3f g = p / voxel;
      const int ix = static_cast<int>(std::floor(g.x() + 0.5f)), iy = static_cast<int>(std::floor(g.y() + 0.5f)),
                iz = static_cast<int>(std::floor(g.z() + 0.5f));
      const Voxel* v = st.VoxelAt(ix, iy, iz, &cache);
      if (!v) {  // unallocated: on to where the ray leaves this block
        prev_s = kNaN;
        tr += std::max(BlockExit(p, dir, ix, iy, iz), 0.f) + 0.01f * voxel;
        continue;
      }
      if (v->weight == 0) {
        prev_s = kNaN;
        tr += voxel;
        continue;
      }
      // The nearest voxel is enough to step; near the surface the trilinear value decides
      // where the crossing is.
      float s = v->sdf();
      bool precise = false;
      if (s < 0.5f) precise = st.Trilinear(p, &s, nullptr, nullptr, &cache);
      if (s < 0) {
        if (prev_s > 0)  // a zero crossing from the front
          Hit(prev_t, tr, prev_s, s, prev_precise, precise, dir, len, static_cast<std::size_t>(y) * k.w + x, &cache,
              out);
        return;  // behind a surface (or entered from behind): stop
      }
      prev_precise = precise;
      prev_t = tr;
      prev_s = s;
      tr += std::max(voxel, 0.8f * s * trunc);
    }
  }
};

}  // namespace

void TsdfVolume::Raycast(const Camera& k, const Eigen::Matrix4d& world_from_camera, Maps* out, bool with_color,
                         const Maps* hint) const {
  const VolumeStore& st = impl_->store;
  const float voxel = impl_->o.voxel, trunc = impl_->o.truncation, block = voxel * kBlockSide;
  const int w = k.width, h = k.height;
  const std::size_t n = static_cast<std::size_t>(w) * h;
  out->k = k;
  out->vertex.assign(n, Eigen::Vector3f::Constant(kNaN));
  out->normal.assign(n, Eigen::Vector3f::Constant(kNaN));
  out->color.assign(with_color ? n : 0, Eigen::Vector3f::Constant(kNaN));
  out->depth.assign(n, 0.f);
  const Eigen::Matrix4f wfc = world_from_camera.cast<float>();
  const Eigen::Matrix3f R = wfc.block<3, 3>(0, 0);
  const Eigen::Vector3f t = wfc.block<3, 1>(0, 3);
  const Pinhole pin(k);

  TileRanges ranges(w, h);
  const Eigen::Matrix3f Rt = R.transpose();
  AddBlockRanges(st, pin, Rt, -Rt * t, block, &ranges);
  if (hint && hint->k.width == w && hint->k.height == h && hint->depth.size() == n)
    NarrowByHint(*hint, w, h, trunc, &ranges);

  const RayMarch march{st, pin, R, t, voxel, trunc, with_color};
  ParallelForChunks(0, static_cast<std::size_t>(h), 4, [&](std::size_t y0, std::size_t y1) {
    for (int y = static_cast<int>(y0); y < static_cast<int>(y1); ++y)
      for (int x = 0; x < w; ++x) {
        const std::size_t tile = ranges.Tile(x, y);
        if (ranges.zmax[tile] <= 0 || ranges.zmin[tile] >= kMaxRayDepth) continue;
        march.Cast(x, y, ranges.zmin[tile], std::min(ranges.zmax[tile], kMaxRayDepth), out);
      }
  });
}

}  // namespace lp
