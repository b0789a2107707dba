#pragma once
/// The glTF export: DIR/scene.gltf + DIR/scene.bin (the mesh with vertex colours, its glowing
/// faces with an emissive material (KHR_materials_emissive_strength), a camera per keyframe,
/// point and directional lights through KHR_lights_punctual) and
/// DIR/environment.hdr (the map, equirectangular in glTF's frame as three.js maps it).
/// docs/formats.md, "Exports".
#include <filesystem>
#include <string>
#include <vector>

#include "exports/export_scene.h"

namespace lp {

/// Luminous efficacy glTF's photometric units are converted with (the one Blender's glTF
/// importer and exporter use): candela = 683 x W/sr, lux = 683 x W/m^2.
inline constexpr double kLumensPerWatt = 683.0;

std::vector<std::string> WriteGltfExport(const ExportScene& scene, const std::filesystem::path& dir);

}  // namespace lp
