#pragma once
/// lights.json (docs/formats.md): an estimate's lighting as other programs take it, the
/// environment map (far) by file, the point lights (near) and the directional lights (a
/// sun) by value.
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "common/image.h"
#include "estimation/light_uncertainty.h"
#include "estimation/lighting.h"

namespace lp {

struct LightsFile {
  /// The map's equirectangular EXR (EnvMap convention), relative to lights.json's folder;
  /// empty when the map is empty.
  std::string environment;
  /// Every light, kind by kind in the file's order of kinds (each kind has its key).
  std::vector<Light> lights;
  /// How well the estimate knows each light (estimation/light_uncertainty.h), one per light
  /// in `lights`' order, or empty (none said). In the file: a point light's
  /// "position_covariance" (3 x 3, m^2) and "intensity_sigma"; a directional light's
  /// "direction_covariance" (3 x 3 in its tangent plane, radians^2) and "irradiance_sigma";
  /// an entry the data do not fix is null (infinite).
  std::vector<LightUncertainty> uncertainty;
  /// Windows' openings (EstimateResult::openings): in the file "openings", one {"id": k,
  /// "area": m^2} each (k = 0, 1, ...), their triangles in openings.ply beside it. A
  /// renderer leaves the mesh's triangles on them out (rays pass through).
  std::vector<std::shared_ptr<const EmitterShape>> openings;
};

/// The file's key for the lights of each kind ("point_lights", "directional_lights").
const char* LightsKey(const PointLight&);
const char* LightsKey(const DirectionalLight&);
const char* LightsKey(const EmitterLight&);

/// The file's text (JSON, 2-space indent, a final newline; every kind's key, an empty
/// array for a kind without lights).
std::string LightsJson(const LightsFile& lights);
/// Parses lights.json text (`name` for errors); keys it does not know are ignored. Throws
/// InputError when malformed (a position or intensity not 3 finite numbers, a negative
/// intensity or radius; a direction of length 0 (others are normalized), a negative
/// irradiance, an angular radius outside [0, pi/2)). A file without "directional_lights"
/// (written before they existed) has none.
LightsFile ParseLightsJson(const std::string& text, const std::string& name);

/// ParseLightsJson of the file at `path`, each emitter given its triangles from the
/// emitters.ply beside it (InputError when an emitter has none there or the file is missing).
LightsFile ReadLightsFile(const std::filesystem::path& path);

/// emitters.ply (docs/formats.md): the emitters' triangles, three vertices each, with the
/// normal of the side that emits, a colour to look at, the `emitter` id and the
/// `radiance_r/g/b` they emit. Written atomically; none when `lights` has no emitter.
void WriteEmittersPly(const std::filesystem::path& file, const std::vector<Light>& lights);

/// openings.ply (docs/formats.md): the openings' triangles in emitters.ply's layout, the
/// `emitter` property holding the opening's id, no radiance. Written atomically; none when
/// there is no opening.
void WriteOpeningsPly(const std::filesystem::path& file,
                      const std::vector<std::shared_ptr<const EmitterShape>>& openings);

/// Reads an equirectangular map file (.exr/.pfm/.png linear, or Radiance .hdr: lights.json's
/// `environment`, `render --envmap`). Throws InputError naming the file when it is not
/// 2:1 or holds a negative or non-finite value.
ImageRGB ReadEquirectMap(const std::filesystem::path& file);

}  // namespace lp
