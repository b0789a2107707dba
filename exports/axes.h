#pragma once
/// Where the bundle's world frame lands in the programs the exports are for (docs/formats.md,
/// "Exports"): Blender's frame (+Z up) and glTF's (+Y up), and the equirectangular mapping
/// both use for a world map (Blender's Environment Texture; three.js's
/// EquirectangularReflectionMapping of an RGBELoader texture, which is the same picture).
#include <Eigen/Core>

#include "common/image.h"

namespace lp {

struct ExportAxes {
  /// `up`: the bundle's up (non-zero; normalized here).
  explicit ExportAxes(const Eigen::Vector3d& up);
  /// The smallest rotation taking `up` to +Z (the identity when `up` is +Z).
  Eigen::Matrix3d blender_from_world;
  /// Blender's frame, then glTF's +Y up: glTF (x, y, z) = Blender (x, z, -y).
  Eigen::Matrix3d gltf_from_world;
  static Eigen::Matrix3d GltfFromBlender();
};

/// Blender's equirectangular mapping of a direction `b` in Blender's frame: u across the
/// image from its left edge, t down from its top row, both in [0, 1]:
/// u = 0.5 - atan2(b.y, b.x) / 2pi (mod 1), t = acos(b.z) / pi. (Cycles' own, with v = 1 - t
/// counted from the bottom.) three.js maps the glTF direction g = (b.x, b.z, -b.y) to the
/// same u and t (u = atan2(g.z, g.x) / 2pi + 0.5, v = asin(g.y) / pi + 0.5).
Eigen::Vector2d BlenderEquirectUt(const Eigen::Vector3d& b);
/// The inverse: the unit direction in Blender's frame of image point (u, t).
Eigen::Vector3d BlenderEquirectDirection(double u, double t);

/// An estimate's map (EnvMap's equirectangular convention around `up`: envmap.exr) as a
/// `height` x 2`height` picture in Blender's mapping: each pixel takes the value of the
/// source pixel its centre's direction falls in (the cells stay sharp; no blur).
ImageRGB BlenderWorldImage(const ImageRGB& map, const Eigen::Vector3d& up, int height);

}  // namespace lp
