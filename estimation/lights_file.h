#pragma once
/// lights.json (docs/formats.md): an estimate's lighting as other programs take it, the
/// environment map (far) by file and the point lights (near) by value.
#include <string>
#include <vector>

#include "estimation/point_light.h"

namespace lp {

struct LightsFile {
  /// The map's equirectangular EXR (EnvMap convention), relative to lights.json's folder;
  /// empty when the map is empty.
  std::string environment;
  std::vector<PointLight> point_lights;
};

/// The file's text (JSON, 2-space indent, a final newline).
std::string LightsJson(const LightsFile& lights);
/// Parses lights.json text (`name` for errors); keys it does not know are ignored. Throws
/// InputError when malformed (a position or intensity not 3 finite numbers, a negative
/// intensity or radius).
LightsFile ParseLightsJson(const std::string& text, const std::string& name);

}  // namespace lp
