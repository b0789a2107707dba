#pragma once
/// Vignetting from a reconstruction instead of a flat target (Kim & Pollefeys' idea): the
/// same surface point, Lambertian, has the same radiance in every keyframe, so the ratio of
/// its values at two image radii is a ratio of vignetting.

#include <vector>

#include "calibration/vignetting.h"
#include "scene/scene_bundle.h"

namespace lp {

/// Points spread over the mesh by area (`max_points`) seen in two or more views of
/// `bundle` (in the image, its 3x3 neighbourhood inside the mask, not occluded: the ray
/// from the camera hits the mesh within 1 cm + 1 % of the point): each pair of sightings
/// with the mean linear value over the 3x3 pixels and the normalized radius.
std::vector<VignettingPair> KeyframeVignettingPairs(const SceneBundle& bundle, int max_points = 20000);

}  // namespace lp
