#include "reconstruction/tsdf_volume.h"

#include <sys/mman.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <new>
#include <type_traits>

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

int BlockHash::Insert(std::uint64_t key, int value) {
  if (2 * (size_ + 1) > slots_.size()) Rehash(2 * slots_.size());
  for (std::size_t i = SplitMix64(key) & mask_;; i = (i + 1) & mask_) {
    Slot& slot = slots_[i];
    if (slot.key == key) return slot.value;
    if (slot.key == kEmpty) {
      slot = {key, value};
      ++size_;
      return value;
    }
  }
}

void BlockHash::Rehash(std::size_t capacity) {
  std::vector<Slot> old = std::move(slots_);
  slots_.assign(capacity, Slot{});
  mask_ = capacity - 1;
  size_ = 0;
  for (const Slot& slot : old)
    if (slot.key != kEmpty) Insert(slot.key, slot.value);
}

static_assert(std::is_trivially_destructible_v<VoxelBlock>);

// ---- BlockArena ----------------------------------------------------------------------

VoxelBlock* BlockArena::New() {
  if (used_ == kPerChunk) {
    void* p = std::aligned_alloc(std::size_t{2} << 20, kChunkBytes);
    if (!p) throw std::bad_alloc();
    madvise(p, kChunkBytes, MADV_HUGEPAGE);  // a hint: without huge pages the chunk still works
    chunks_.emplace_back(static_cast<VoxelBlock*>(p));
    used_ = 0;
  }
  return new (chunks_.back().get() + used_++) VoxelBlock();
}

void BlockArena::Free::operator()(VoxelBlock* p) const { std::free(p); }  // VoxelBlock is trivially destructible

// ---- VolumeStore ---------------------------------------------------------------------

int VolumeStore::AllocateBlock(int bx, int by, int bz) {
  const int next = static_cast<int>(blocks.size());
  const int index = hash.Insert(BlockHash::Key(bx, by, bz), next);
  if (index == next) {
    blocks.push_back(arena.New());
    coords.emplace_back(bx, by, bz);
  }
  return index;
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
  for (const VoxelBlock* b : m.store.blocks) c.store.blocks.push_back(new (c.store.arena.New()) VoxelBlock(*b));
  c.stamp = m.stamp;
  c.frame = m.frame;
  return copy;
}

const TsdfOptions& TsdfVolume::options() const { return impl_->o; }
std::size_t TsdfVolume::BlockCount() const { return impl_->store.blocks.size(); }
std::size_t TsdfVolume::MemoryBytes() const {
  const VolumeStore& st = impl_->store;
  return st.arena.Bytes() + st.blocks.size() * (sizeof(VoxelBlock*) + sizeof(Eigen::Vector3i) + sizeof(int)) +
         st.hash.Bytes();
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
  const float per_block = 1.f / block;
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
          const Eigen::Vector3i b(static_cast<int>(std::floor(p.x() * per_block)),
                                  static_cast<int>(std::floor(p.y() * per_block)),
                                  static_cast<int>(std::floor(p.z() * per_block)));
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
  bool same_camera;               ///< colour on the depth's pixel grid: a voxel's colour pixel is its depth pixel

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
    same_camera = color && !color_from_depth && color->width == k.w && color->height == k.h && ck.fx == k.fx &&
                  ck.fy == k.fy && ck.cx == k.cx && ck.cy == k.cy;
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

  /// A block row by row: first where each voxel of the row projects (no branches, so the
  /// compiler vectorizes it), then the running averages of those that project onto a depth.
  void Block(VoxelBlock& blk, const Eigen::Vector3i& origin) const {
    const Eigen::Vector3f step = Rt.col(0) * voxel;
    for (int lz = 0; lz < kBlockSide; ++lz)
      for (int ly = 0; ly < kBlockSide; ++ly) {
        const Eigen::Vector3f row_start = Rt * (Eigen::Vector3f(origin.x(), origin.y() + ly, origin.z() + lz) * voxel) + tc;
        float px[kBlockSide], py[kBlockSide], pz[kBlockSide];
        int pix[kBlockSide];
        ProjectRow(row_start, step, px, py, pz, pix);
        for (int lx = 0; lx < kBlockSide; ++lx)
          if (pix[lx] >= 0)
            UpdateVoxel(blk, VolumeStore::LocalIndex(lx, ly, lz), Eigen::Vector3f(px[lx], py[lx], pz[lx]),
                        static_cast<std::size_t>(pix[lx]));
      }
  }

  /// Camera-frame points of a row of voxels and the depth pixel each falls in (nearest),
  /// -1 behind the camera or outside the image.
  void ProjectRow(const Eigen::Vector3f& start, const Eigen::Vector3f& step, float* px, float* py, float* pz,
                  int* pix) const {
    for (int lx = 0; lx < kBlockSide; ++lx) {
      const float f = static_cast<float>(lx);
      px[lx] = start.x() + step.x() * f;
      py[lx] = start.y() + step.y() * f;
      pz[lx] = start.z() + step.z() * f;
    }
    for (int lx = 0; lx < kBlockSide; ++lx) {
      const float z = pz[lx] > 0 ? pz[lx] : 1.f, iz = 1.f / z;
      // +0.5 and truncation round to nearest for the in-image (non-negative) range.
      const float uf = k.fx * px[lx] * iz + k.cx + 0.5f, vf = k.fy * py[lx] * iz + k.cy + 0.5f;
      const bool in = pz[lx] > 0 && uf >= 0 && vf >= 0 && uf < k.w && vf < k.h;  // NaN fails too
      const int u = in ? static_cast<int>(uf) : 0, v = in ? static_cast<int>(vf) : 0;
      pix[lx] = in ? v * k.w + u : -1;
    }
  }

  void UpdateVoxel(VoxelBlock& blk, int li, const Eigen::Vector3f& pc, std::size_t pix) const {
    const float d = depth[pix];
    if (d <= 0) return;
    const float sdf = (d - pc.z()) * lambda[pix];
    if (sdf < -trunc) return;
    const float tsdf = std::min(1.f, sdf / trunc);
    Voxel& vx = blk.v[li];
    vx.set_sdf((vx.sdf() * vx.weight + tsdf) * inv[vx.weight]);
    vx.weight = static_cast<std::uint16_t>(std::min<int>(vx.weight + 1, max_w));
    if (!color || std::abs(sdf) > 0.5f * trunc) return;
    if (same_camera) return Mix(blk.c[li], color->data.data() + 3 * pix);
    Color(blk.c[li], extrinsics ? Eigen::Vector3f(Rcd * pc + tcd) : pc);
  }

  void Color(VoxelColor& vc, const Eigen::Vector3f& pcol) const {
    if (pcol.z() <= 0) return;
    const float iz = 1.f / pcol.z();
    const float uf = ck.fx * pcol.x() * iz + ck.cx + 0.5f, vf = ck.fy * pcol.y() * iz + ck.cy + 0.5f;
    if (!(uf >= 0 && vf >= 0 && uf < color->width && vf < color->height)) return;  // NaN fails too
    const int cu = static_cast<int>(uf), cv = static_cast<int>(vf);  // nearest
    if (!color_z.empty() && pcol.z() > color_z[static_cast<std::size_t>(cv) * color->width + cu] + trunc) return;
    Mix(vc, color->at(cu, cv));
  }

  /// The running mean of a voxel's colour takes `c` (linear RGB; skipped unless finite).
  void Mix(VoxelColor& vc, const float* c) const {
    if (!(std::isfinite(c[0]) && std::isfinite(c[1]) && std::isfinite(c[2]))) return;
    const float cw = vc.weight * (1.f / 65535.f), to_mean = inv[vc.weight];
    auto mix = [&](std::uint16_t old, float value) {
      const float v = (old * cw + std::clamp(value, 0.f, 1.f)) * to_mean;
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
  // The band lists each block many times: a small direct-mapped table of the blocks just
  // seen spares most of the hash's probes.
  constexpr std::size_t kRecent = 4096;
  std::vector<std::pair<Eigen::Vector3i, int>> recent(kRecent, {Eigen::Vector3i(INT32_MIN, 0, 0), -1});
  for (const auto& list : found)
    for (const Eigen::Vector3i& b : list) {
      if (b.cwiseAbs().maxCoeff() >= kMaxBlock) continue;  // kilometres away: not a room
      auto& seen = recent[(static_cast<std::size_t>(b.x()) * 73856093u ^ static_cast<std::size_t>(b.y()) * 19349663u ^
                           static_cast<std::size_t>(b.z()) * 83492791u) &
                          (kRecent - 1)];
      if (seen.first == b) continue;  // touched already this frame
      const int index = st.AllocateBlock(b.x(), b.y(), b.z());
      LP_CHECK(index >= 0, "block hash returned no index");
      seen = {b, index};
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

/// Rays a raycast marches in turn (RayState).
constexpr int kRayLanes = 4;

/// How far in front of and behind a ray's measured depth (its 3x3 neighbourhood's nearest
/// and farthest) the surface is sought, beyond the truncation: depth noise at a few metres.
constexpr float kMeasuredMargin = 0.05f;

/// The nearest and farthest measured depth around pixel (x, y); false unless all 9 have one.
bool MeasuredRange(const std::vector<float>& depth, int w, int h, int x, int y, float* lo, float* hi) {
  if (x < 1 || y < 1 || x + 1 >= w || y + 1 >= h) return false;
  float a = std::numeric_limits<float>::max(), b = 0;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      const float z = depth[static_cast<std::size_t>(y + dy) * w + x + dx];
      if (!(z > 0)) return false;
      a = std::min(a, z);
      b = std::max(b, z);
    }
  *lo = a;
  *hi = b;
  return true;
}

/// A ray under way (RayMarch::Step advances it one step). `cache` is kept from ray to ray:
/// neighbouring rays cross the same blocks.
struct RayState {
  int x = 0, y = 0;
  Eigen::Vector3f dir = Eigen::Vector3f::Zero();
  float len = 1, tr = 0, t_end = -1, prev_t = -1, prev_s = kNaN;
  bool prev_precise = false;
  float whole_min = 0, whole_max = -1;  ///< the range searched next if this search finds nothing (max < 0: none)
  BlockCache cache;
};
enum class RayEnd { kGoing, kHit, kNothing };

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
  bool Hit(float a, float b, float prev_s, float s, bool prev_precise, bool precise, const Eigen::Vector3f& dir,
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
      return true;
    }
    return false;
  }

  /// A ray set off from pixel (x, y) between depths zmin and zmax (along the axis).
  void Start(RayState& r, int x, int y, float zmin, float zmax) const {
    const Eigen::Vector3f ray_c((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1.f);
    r.x = x;
    r.y = y;
    r.len = ray_c.norm();
    r.dir = R * (ray_c / r.len);
    // Distance along the ray from depth along the axis: t = z * len.
    r.tr = zmin * r.len;
    r.t_end = zmax * r.len;
    r.prev_t = -1;
    r.prev_s = kNaN;
    r.prev_precise = false;
  }

  /// One step of a ray's march to the first zero crossing from the front.
  RayEnd Step(RayState& r, TsdfVolume::Maps* out) const {
    if (!(r.tr <= r.t_end)) return RayEnd::kNothing;
    const Eigen::Vector3f p = t + r.dir * r.tr;
    const Eigen::Vector3f g = p / voxel;
    const int ix = static_cast<int>(std::floor(g.x() + 0.5f)), iy = static_cast<int>(std::floor(g.y() + 0.5f)),
              iz = static_cast<int>(std::floor(g.z() + 0.5f));
    const Voxel* v = st.VoxelAt(ix, iy, iz, &r.cache);
    if (!v) {  // unallocated: on to where the ray leaves this block
      r.prev_s = kNaN;
      r.tr += std::max(BlockExit(p, r.dir, ix, iy, iz), 0.f) + 0.01f * voxel;
      return RayEnd::kGoing;
    }
    if (v->weight == 0) {
      r.prev_s = kNaN;
      r.tr += voxel;
      return RayEnd::kGoing;
    }
    // The nearest voxel is enough to step; near the surface the trilinear value decides
    // where the crossing is.
    float s = v->sdf();
    bool precise = false;
    if (s < 0.5f) precise = st.Trilinear(p, &s, nullptr, nullptr, &r.cache);
    if (s < 0) {
      if (!(r.prev_s > 0)) return RayEnd::kNothing;  // behind a surface (or entered from behind): stop
      // A zero crossing from the front.
      return Hit(r.prev_t, r.tr, r.prev_s, s, r.prev_precise, precise, r.dir, r.len,
                 static_cast<std::size_t>(r.y) * k.w + r.x, &r.cache, out)
                 ? RayEnd::kHit
                 : RayEnd::kNothing;
    }
    r.prev_precise = precise;
    r.prev_t = r.tr;
    r.prev_s = s;
    r.tr += std::max(voxel, 0.8f * s * trunc);
    return RayEnd::kGoing;
  }
};

/// The rays of one tile. Several march in turn, a step each: one ray's step does not wait on
/// the voxel another's is loading (a march is a chain of loads, each waiting on the last).
/// With `measured` a ray first searches around its pixel's measured depth (MeasuredRange).
void MarchTile(const RayMarch& march, const TileRanges& ranges, int tx, int ty, const std::vector<float>* measured,
               TsdfVolume::Maps* out) {
  const std::size_t tile = static_cast<std::size_t>(ty) * ranges.tw + tx;
  if (ranges.zmax[tile] <= 0 || ranges.zmin[tile] >= kMaxRayDepth) return;
  const float zmin = ranges.zmin[tile], zmax = std::min(ranges.zmax[tile], kMaxRayDepth);
  const float margin = march.trunc + kMeasuredMargin;
  const int w = march.k.w, h = march.k.h, x0 = tx * kTile, y0 = ty * kTile, tw = std::min(w, x0 + kTile) - x0,
            count = tw * (std::min(h, y0 + kTile) - y0);
  int next = 0;
  auto launch = [&](RayState& r) {  // the tile's next pixel
    if (next >= count) return false;
    const int x = x0 + next % tw, y = y0 + next / tw;
    ++next;
    float lo, hi;
    if (measured && MeasuredRange(*measured, w, h, x, y, &lo, &hi)) {
      march.Start(r, x, y, std::max(lo - margin, 0.f), std::min(hi + margin, kMaxRayDepth));
      r.whole_min = zmin;
      r.whole_max = zmax;
    } else {
      march.Start(r, x, y, zmin, zmax);
      r.whole_max = -1;
    }
    return true;
  };
  RayState lanes[kRayLanes];
  bool going[kRayLanes];
  int active = 0;
  for (int l = 0; l < kRayLanes; ++l) active += going[l] = launch(lanes[l]);
  while (active > 0)
    for (int l = 0; l < kRayLanes; ++l) {
      if (!going[l]) continue;
      RayState& r = lanes[l];
      const RayEnd end = march.Step(r, out);
      if (end == RayEnd::kGoing) continue;
      if (end == RayEnd::kNothing && r.whole_max >= 0) {  // nothing around the measured depth
        march.Start(r, r.x, r.y, r.whole_min, r.whole_max);
        r.whole_max = -1;
        continue;
      }
      if (!(going[l] = launch(r))) --active;
    }
}

}  // namespace

void TsdfVolume::Raycast(const Camera& k, const Eigen::Matrix4d& world_from_camera, Maps* out, bool with_color,
                         const Maps* hint, const std::vector<float>* measured) const {
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
  const bool guided = measured && measured->size() == n;
  // Tile by tile: a tile's rays cross the same few voxel blocks, which stay in the cache.
  ParallelForChunks(0, static_cast<std::size_t>(ranges.th), 1, [&](std::size_t ty0, std::size_t ty1) {
    for (int ty = static_cast<int>(ty0); ty < static_cast<int>(ty1); ++ty)
      for (int tx = 0; tx < ranges.tw; ++tx) MarchTile(march, ranges, tx, ty, guided ? measured : nullptr, out);
  });
}

}  // namespace lp
