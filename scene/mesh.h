#pragma once
/// Triangle mesh with per-vertex linear albedo: the scene geometry the estimator traces.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace lp {

struct Mesh {
  std::vector<Eigen::Vector3f> positions;  ///< metres, world frame
  std::vector<Eigen::Vector3f> normals;    ///< unit, per vertex; empty = computed on load
  std::vector<Eigen::Vector3f> albedo;     ///< linear RGB in [0, 1], per vertex
  /// Optional, per vertex: the colour the camera saw (linear RGB in image units, shading
  /// included; a reconstruction fuses it in [0, 1]), when `albedo` was derived from it. The estimator then
  /// de-lights it under its estimate to refine the albedo (scene/albedo.h); empty when
  /// the albedo is known.
  std::vector<Eigen::Vector3f> shaded;
  /// Optional, per vertex (emitters.ply, docs/formats.md): the glowing surface it belongs
  /// to (`emitter`, -1: none) and the radiance it emits (`radiance_r/g/b`, linear, image
  /// units); empty in other meshes.
  std::vector<int> label;
  std::vector<Eigen::Vector3f> emission;
  std::vector<Eigen::Vector3i> triangles;  ///< vertex indices

  /// Appends another mesh (indices shifted).
  void Append(const Mesh& other);
};

/// A UV sphere (rings x segments) with outward normals and one albedo.
Mesh UvSphere(const Eigen::Vector3f& centre, float radius, const Eigen::Vector3f& albedo, int rings = 24,
              int segments = 48);

/// Reads an ASCII or binary PLY (scene-bundle format: x y z, optional nx ny nz,
/// red green blue as sRGB-encoded uchar, faces as vertex_indices lists; polygons
/// are fanned into triangles). Colours are decoded to linear albedo; a mesh without
/// colours gets albedo 0.5. Throws InputError naming the file on any problem.
Mesh ReadPly(const std::filesystem::path& path);

/// Parses PLY bytes (what ReadPly does after reading the file); `name` is used in errors.
Mesh ParsePly(const std::string& bytes, const std::string& name);

/// Writes a binary little-endian PLY with normals and sRGB-encoded colours, atomically.
void WritePly(const std::filesystem::path& path, const Mesh& mesh);

/// Fills `normals` with area-weighted vertex normals (used when the file has none).
void ComputeVertexNormals(Mesh* mesh);

/// Taubin's smoothing (lambda | mu, 1995): `iterations` pairs of a Laplacian step towards
/// the neighbours' mean (`lambda` > 0) and one back (`mu` < -lambda). High frequencies
/// (noise a few vertices across) fade while the shape does not shrink as plain Laplacian
/// smoothing does. Normals are recomputed from the triangles.
void SmoothMesh(Mesh* mesh, int iterations, float lambda = 0.5f, float mu = -0.53f);

/// Validates indices and values; removes degenerate (zero-area or repeated-index)
/// triangles and returns how many were removed. Throws InputError (with `name`)
/// if nothing usable remains.
int SanitizeMesh(Mesh* mesh, const std::string& name);

/// The same surface with at least `min_triangles` triangles: the largest triangle is split
/// at the midpoint of its longest edge until there are enough (normals and albedo
/// interpolated; the neighbour is not split, so the new vertex is a T-junction on a
/// surface that does not change). For scaling tests and benchmarks.
Mesh RefineMesh(const Mesh& mesh, int min_triangles);

/// The mesh with the triangles marked in `drop` (one flag per triangle) left out; every
/// vertex and per-vertex value kept, so values per vertex still line up (a window's opening
/// drawn or exported as no surface).
Mesh WithoutTriangles(const Mesh& mesh, const std::vector<std::uint8_t>& drop);

/// Axis-aligned bounds of the vertices used by triangles.
void MeshBounds(const Mesh& mesh, Eigen::Vector3f* lo, Eigen::Vector3f* hi);

/// The centre of those bounds and the radius of the sphere through their corners (at least
/// 1e-9): the scene's centre and size as the tracer and the estimator take them.
void BoundingSphere(const Mesh& mesh, Eigen::Vector3d* centre, double* radius);

}  // namespace lp
