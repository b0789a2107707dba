#pragma once
/// A truncated signed distance volume with weights and colour, stored sparsely: voxel
/// blocks of 8^3 found through a hash of their coordinates (as InfiniTAM's voxel hashing
/// and Open3D's VoxelBlockGrid), allocated only near observed surfaces. A 3 m room at
/// 1 cm needs a few tens of thousands of blocks (12 bytes per voxel, 6 KiB per block).

#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "capture/frame.h"
#include "common/image.h"
#include "scene/mesh.h"

namespace lp {

struct TsdfOptions {
  float voxel = 0.01f;       ///< voxel edge, metres (1 cm for a room, 4 mm for a table top)
  float truncation = 0.04f;  ///< metres; the signed distance is clamped to +-truncation
  float max_weight = 64;     ///< running-average window (frames)
};

/// A voxel: signed distance over truncation in [-1, 1] (negative behind the surface) in
/// 16-bit fixed point, and its weight (observations, capped). 4 bytes, so a raycast reads
/// 16 voxels per cache line; the colour lives beside it (VoxelColor).
struct Voxel {
  std::int16_t sdf_q = 32767;
  std::uint16_t weight = 0;
  float sdf() const { return sdf_q * (1.f / 32767.f); }
  void set_sdf(float s) { sdf_q = static_cast<std::int16_t>(s * 32767.f + (s >= 0 ? 0.5f : -0.5f)); }
};

/// The mean linear colour of the observations near the surface (16-bit fixed point in
/// [0, 1]) and how many there were (capped).
struct VoxelColor {
  std::uint16_t r = 0, g = 0, b = 0, weight = 0;
  Eigen::Vector3f rgb() const { return Eigen::Vector3f(r, g, b) * (1.f / 65535.f); }
};

constexpr int kBlockShift = 3;  ///< blocks of 2^3 = 8 voxels a side
constexpr int kBlockSide = 1 << kBlockShift;
constexpr int kBlockMask = kBlockSide - 1;
constexpr int kBlockVoxels = kBlockSide * kBlockSide * kBlockSide;

/// Maps surfaces seen from a camera (world frame, metres): depth images go in, raycasts and
/// a triangle mesh come out.
class TsdfVolume {
 public:
  explicit TsdfVolume(const TsdfOptions& options);
  ~TsdfVolume();
  TsdfVolume(TsdfVolume&&) noexcept;
  /// A deep copy (every voxel block).
  TsdfVolume Clone() const;
  TsdfVolume& operator=(TsdfVolume&&) noexcept;

  /// Fuses a depth map (metres along the optical axis, 0 = invalid, camera `k`) taken from
  /// `world_from_camera`. Only blocks within the truncation band of a measurement are
  /// allocated and updated. `color` (linear RGB, camera `color_k`; may be null) updates the
  /// colour of voxels within half the truncation of the surface; the colour camera is at
  /// the depth camera's pose, or moved by `color_from_depth` when given (unregistered
  /// frames). Returns the number of blocks updated.
  std::size_t Integrate(const std::vector<float>& depth, const Camera& k, const ImageRGB* color,
                        const Camera& color_k, const Eigen::Matrix4d& world_from_camera,
                        const Eigen::Matrix4d* color_from_depth = nullptr);

  /// What a camera sees of the model, world frame; NaN where a ray hits nothing.
  struct Maps {
    Camera k;
    std::vector<Eigen::Vector3f> vertex, normal, color;
    std::vector<float> depth;  ///< along the optical axis, 0 = nothing
  };
  /// Casts a ray per pixel of camera `k` at `world_from_camera` to the zero crossing of
  /// the signed distance (from front to back; rays start near the allocated blocks). With
  /// `hint`, a raycast of the same camera from a nearby pose (the previous frame), each
  /// 8x8 tile whose neighbourhood was fully hit there searches only around those depths
  /// (+-(truncation + 5 cm)): fewer steps through the volume. With `measured`, the depth
  /// this camera measured at this pose (k's size, metres, 0 = none; the frame just fused),
  /// each ray whose 3x3 neighbourhood has a depth first searches only around it
  /// (+-(truncation + 5 cm)), and the whole range only if it finds no surface there.
  void Raycast(const Camera& k, const Eigen::Matrix4d& world_from_camera, Maps* out, bool with_color = false,
               const Maps* hint = nullptr, const std::vector<float>* measured = nullptr) const;

  /// Marching cubes over the allocated blocks (cubes whose 8 corners have weight >=
  /// min_weight); vertices shared between cubes, normals from the triangles, pointing to
  /// free space; albedo = the voxels' mean linear colour (interpolated along the edge).
  Mesh ExtractMesh(float min_weight = 1.f) const;

  /// Trilinear signed distance in metres at a world point (NaN outside observed space).
  /// Fused along camera rays (projective): exact in sign and zero on the surface, at
  /// least the Euclidean distance off it.
  float SignedDistance(const Eigen::Vector3f& p) const;

  std::size_t BlockCount() const;
  std::size_t MemoryBytes() const;
  const TsdfOptions& options() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lp
