#pragma once
// Small scenes built in code for closed-form tests.
#include <functional>
#include <string>
#include <vector>

#include "scene/scene_bundle.h"

namespace lp::test {

/// Square in the plane z = 0 (normal +z), side `size`, centred at the origin, albedo rho.
Mesh Plane(double size, double rho);
/// A 1 m square of albedo `rho` in the plane z = 0 centred at the origin, a vertex every
/// centimetre; each vertex's normal tilted at random (a fixed seed) by up to `max_tilt`
/// radians (a scan's noisy normals), straight up with 0.
Mesh FineFloor(double rho, double max_tilt = 0);
/// Axis-aligned horizontal square at height z facing down and up (two-sided occluder).
Mesh Square(double cx, double cy, double z, double half, double rho);
/// UV sphere, outward normals.
Mesh Ball(double radius, double rho, int rings = 32, int segments = 64);

/// The two meshes as one (b's triangles after a's).
Mesh Merge(Mesh a, const Mesh& b);

/// A camera at `eye` looking at `target`, world up +z.
Camera LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, int w, int h, double hfov_deg);

/// What `f` throws as InputError ("" when it throws nothing).
std::string ErrorOf(const std::function<void()>& f);

/// A view with every pixel valid and a zero image.
View BlankView(const Camera& cam);

}  // namespace lp::test
