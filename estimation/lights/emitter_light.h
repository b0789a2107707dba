#pragma once
/// A glowing surface of the scan (a lamp's shade, a frosted window, a screen): triangles of
/// the mesh that emit light of their own, diffusely, on the side the cameras saw them from.
/// lights.json's "emitters" with their triangles in emitters.ply (docs/formats.md). What only
/// this kind knows: its unit column (next-event estimation to its triangles from every
/// shading vertex, and the camera's own view of it: the pixels that see it receive its
/// radiance directly; none for a pane in a hole), the light it sends to a point, the radiance a camera sees on it. It
/// has no shape to refine: its triangles are where the keyframes saw it glow; its scale, the
/// unknown, is its mean emitted radiance.
#include <cstdint>
#include <limits>
#include <memory>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "estimation/shading_vertices.h"
#include "scene/mesh.h"
#include "scene/ray_tracer.h"

namespace lp {

/// Shadow rays from a shading vertex to an emitter's triangles (stratified by area).
constexpr int kEmitterShadowRays = 4;

/// An emitter's triangles, with what sampling them and telling a point on them needs.
struct EmitterShape {
  std::vector<Eigen::Vector3f> a, b, c;  ///< each triangle's corners, world frame, metres
  std::vector<Eigen::Vector3f> normal;   ///< each triangle's unit normal on the side that emits
  std::vector<double> cumulative;        ///< the areas summed up to each triangle (the last: area)
  double area = 0;                       ///< m^2
  /// The cell size of `cells` (metres), and how far off a triangle's plane a point on it
  /// may lie (half a cell: a traced mesh lies a little off the one the triangles came from).
  double cell = 0.02;
  /// Cells of `cell` metres the triangles pass through or lie within half a cell of (a key of
  /// the three indices), each with those triangles.
  std::unordered_map<std::uint64_t, std::vector<int>> cells;
};

/// The shape of `triangles` of `mesh`, each emitting on the side of `facing` (one per
/// triangle, any length > 0: the side its cameras saw it from). Degenerate triangles are
/// left out.
std::shared_ptr<const EmitterShape> MakeEmitterShape(const Mesh& mesh, const std::vector<int>& triangles,
                                                     const std::vector<Eigen::Vector3f>& facing);

/// Whether a surface point lies on the shape, seen from the side of `towards_viewer` (a
/// unit vector from the point towards whoever looks at it): within half a cell of a
/// triangle's plane, inside its edges (by a millimetre), on the side that emits.
bool OnEmitter(const EmitterShape& shape, const Eigen::Vector3d& point, const Eigen::Vector3d& towards_viewer);
/// The shape's triangle `point` lies on (as OnEmitter, either side), or -1.
int EmitterTriangleAt(const EmitterShape& shape, const Eigen::Vector3d& point);

/// Triangle t's centre (its corners' mean), where a shape is looked up for it.
Eigen::Vector3d TriangleCentre(const Mesh& mesh, std::size_t t);
/// Per triangle of `mesh`: 1 where its centre lies on one of `shapes` (EmitterTriangleAt;
/// a window's opening: the triangles a tracer leaves out, RayTracer(mesh, open)).
std::vector<std::uint8_t> TrianglesOnShapes(const Mesh& mesh,
                                            const std::vector<std::shared_ptr<const EmitterShape>>& shapes);
/// The shape of the triangles of `mesh` on `shape` (facing as its own), or null when none is:
/// a shape moved onto another mesh of the same surface (a traced mesh's onto the bundle's).
/// `mesh` without its triangles on `shapes` (TrianglesOnShapes; every vertex kept): a
/// window's openings drawn or exported as no surface.
Mesh WithoutShapes(const Mesh& mesh, const std::vector<std::shared_ptr<const EmitterShape>>& shapes);
/// With `taken` (per triangle of `mesh`), the triangles taken already are left out and those
/// on the shape marked taken: shapes moved one after another share no triangle (a triangle
/// at the seam of two, within a millimetre of both, goes to the first).
std::shared_ptr<const EmitterShape> ShapeOnMesh(const Mesh& mesh, const EmitterShape& shape,
                                                std::vector<std::uint8_t>* taken = nullptr);

/// The sum of its triangles' normals (the side each emits on) weighted by their areas: its
/// length is the area for a flat shape, less the more it bends.
Eigen::Vector3d FacingSum(const EmitterShape& shape);
/// The shape's centre: its triangles' centroids weighted by their areas.
Eigen::Vector3d Centroid(const EmitterShape& shape);
/// The shape's outline: the edges of its triangles that no other of its triangles shares
/// (corners compared exactly: triangles cut from one mesh share theirs), each with the
/// normal of the triangle it bounds.
struct OutlineEdge {
  Eigen::Vector3f from, to, normal;
};
std::vector<OutlineEdge> Outline(const EmitterShape& shape);

/// The share of `a`'s area on `b`: points on a grid of each of a's triangles (60 x 60 / 2 a
/// triangle, weighted by area) that lie on b (OnEmitter, either side: within half of b's cell
/// of one of its triangles' planes, inside its edges; or within `within` metres of it, where
/// that is more, along a's normal). An intersection over union by area is
/// area(a) x AreaOn(a, b) over area(a) + area(b) - that.
double AreaOn(const EmitterShape& a, const EmitterShape& b, double within = 0);

struct EmitterLight {
  int id = 0;  ///< its number in lights.json and emitters.ply
  std::shared_ptr<const EmitterShape> shape;
  /// Mean emitted radiance, image units (W/(m^2 sr) when the images are radiance), the same
  /// in every direction on its emitting side.
  Eigen::Vector3d radiance = Eigen::Vector3d::Zero();
  /// A pane over a hole in the mesh (a window whose glass returned no depth: frosted, or a
  /// curtain): its triangles lie on no surface of the mesh. Its light reaches the room through
  /// the hole; no surface point glows with it (a wall's rim inside its rectangle does not),
  /// and it is never moved onto the mesh's triangles.
  bool in_a_hole = false;
  double Area() const { return shape ? shape->area : 0.0; }
  /// pi x radiance x area: what it emits (image units x m^2 x sr; W when the images are
  /// radiance).
  Eigen::Vector3d Power() const;
};

/// The column of the emitter at unit radiance: out[3*row + c], the light its triangles send
/// to each row's shading vertices (kEmitterShadowRays each, shadowed, one-sided) plus the
/// camera's direct view of it (ShadingVertices::camera of the vertices on it). A vertex's
/// estimate is at most pi (the irradiance a unit-radiance emitter can give: all of the
/// hemisphere): a vertex beside it draws points a centimetre away at a few of its 4 rays,
/// and cos cos / d^2 made fireflies that changed the 3DJ recording's fit by 84 % a round
/// (docs/benchmarks.md, session 44). It has no shape: its derivatives are all zeros.
/// ColumnOut: with the halves' difference when asked.
void UnitColumn(const RayTracer& scene, const ShadingVertices& vertices, const EmitterLight& light,
                const ColumnOut& out);

/// The irradiance (image units) the emitter sends to a surface point `origin` of shading
/// normal `n` and geometric normal `g`: one shadow ray to a point of its triangles drawn by
/// area from `key`, counted in `rays`; at most pi x its radiance (as UnitColumn's).
Eigen::Vector3d Irradiance(const RayTracer& scene, const EmitterLight& light, const Eigen::Vector3d& origin,
                           const Eigen::Vector3d& n, const Eigen::Vector3d& g, std::uint64_t key,
                           std::int64_t* rays);

/// The radiance a viewer sees leave `point` (on a surface, `towards_viewer` unit) by the
/// emitter's own light: its radiance there, else 0.
inline Eigen::Vector3d Emission(const EmitterLight& light, const Eigen::Vector3d& point,
                                const Eigen::Vector3d& towards_viewer) {
  if (!light.shape || light.in_a_hole || !OnEmitter(*light.shape, point, towards_viewer)) return Eigen::Vector3d::Zero();
  return light.radiance;
}

/// What a camera ray sees of a pane over a hole (EmitterLight::in_a_hole; 0 for any other
/// emitter, which Emission gives on its surface): its radiance where the ray from `origin`
/// along unit `dir` crosses one of its triangles, from the side that emits, nearer than
/// `before` (where the ray first meets the scene; infinity when it leaves it) by more than
/// its cell (a wall's rim a little behind the pane's plane is wall, as Emission says).
Eigen::Vector3d SeenInAHole(const EmitterLight& light, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                            double before);

inline bool SameShape(const EmitterLight& a, const EmitterLight& b) { return a.shape == b.shape; }
inline Eigen::Vector3d& Scale(EmitterLight& l) { return l.radiance; }
inline const Eigen::Vector3d& Scale(const EmitterLight& l) { return l.radiance; }
/// No shape coordinates: its triangles stay where the keyframes saw them glow.
inline int ShapeDims(const EmitterLight&) { return 0; }
inline Eigen::Matrix3d ShapeBasis(const EmitterLight&) { return Eigen::Matrix3d::Identity(); }
inline EmitterLight Moved(EmitterLight l, const double*) { return l; }
inline int CompassMoves(const EmitterLight&) { return 0; }
inline double CompassUnit(const EmitterLight&, const Eigen::Vector3d&) { return 1.0; }
inline EmitterLight CompassMove(EmitterLight l, int, double) { return l; }
/// 0 for the same triangles, else infinite (two emitters are never moved into each other).
inline double ShapeDistance(const EmitterLight& now, const EmitterLight& was, const Eigen::Vector3d&) {
  return now.shape == was.shape ? 0.0 : std::numeric_limits<double>::infinity();
}

}  // namespace lp
