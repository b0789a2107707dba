#pragma once
/// Albedo from the fused colour. A voxel's mean linear colour is albedo times shading
/// (the light we want to estimate is baked in): rendered under any light, a mesh coloured
/// that way explains the images with a uniform environment. Real scenes are mostly made of
/// surfaces of one material, so the mesh is split into segments of one chromaticity
/// (joined across edges whose colour changes smoothly) and each segment gets its mean
/// colour: the shading's variation within a segment is then left for the estimator to
/// explain with light.
#include "scene/mesh.h"

namespace lp {

struct AlbedoOptions {
  bool segment = true;          ///< false: keep the per-vertex mean colour
  float max_chroma_step = 0.03f;  ///< join neighbours whose chromaticity differs less than this
  float max_log_step = 0.15f;     ///< ... and whose log luminance differs less than this
  float max_chroma_spread = 0.06f;  ///< segments whose mean chromaticities differ more stay apart
  float max_log_spread = 1e9f;     ///< segments whose mean log luminances differ more stay apart
  int min_segment = 200;        ///< vertices: smaller segments keep their per-vertex colour
  /// Segments apart on the surface (not joined by an edge) whose mean chromaticities differ
  /// less than max_chroma_spread and mean log luminances less than this are one material
  /// too (a checker's squares, tiles, one paint on two walls); 0: never joined.
  float max_apart_log_spread = 0;
};

/// The largest albedo a refined or scaled albedo is given (no real surface reflects all).
inline constexpr float kMaxAlbedo = 0.95f;

/// Replaces each segment's per-vertex albedo by the segment's mean; returns the number of
/// segments flattened. `labels`, when given, receives per vertex its flattened segment
/// (0 .. the count - 1) or -1 (a vertex of a segment too small, that keeps its colour).
int FlattenAlbedo(Mesh* mesh, const AlbedoOptions& options = {}, std::vector<int>* labels = nullptr);

/// The segmentation of de-lit colours: as FlattenAlbedo's, and segments whose mean log
/// luminances differ by more than max_log_step stay apart too (once the light is divided
/// out, a step in brightness is a material's; in the shaded colours it may be the light's);
/// segments apart whose means are alike (log luminances within 0.5) are joined (once the
/// light is divided out, two squares of one checker are one material wherever they are).
AlbedoOptions DelitAlbedoOptions();

/// Refines a mesh's albedo under an estimate of the light (intrinsic decomposition): each
/// vertex's `shaded` colour divided by its grey irradiance `irradiance[v]` (any positive
/// unit; below 5 % of the median it is taken as 5 % of the median: unlit vertices) is its
/// albedo as the estimate explains it; that is segmented and flattened as FlattenAlbedo
/// does with `options`, scaled so its median luminance over the vertices is `median` (the
/// rule the estimate's albedo was scaled by before it was de-lit: --room-albedo) or, with
/// `median` 0, so its mean is `scale` times that of the colours seen (the colours' own
/// scale), and clipped to [0, kMaxAlbedo]. Either way a second pass starts from the same
/// scale. Needs mesh->shaded; returns the segments, or -1 when it keeps the albedo as it
/// was (no vertex lit, or every colour seen black). `labels`: as FlattenAlbedo's.
int DelightAlbedo(Mesh* mesh, const std::vector<float>& irradiance, const AlbedoOptions& options = DelitAlbedoOptions(),
                  double scale = 1, double median = 0, std::vector<int>* labels = nullptr);

/// The factor that takes `mesh`'s albedo to one whose median luminance over the vertices
/// is `median` (1 when that is black or `median` is 0).
double AlbedoScaleTo(const Mesh& mesh, double median);
/// Multiplies the albedo by `scale`, clipped to [0, kMaxAlbedo].
void ScaleAlbedo(Mesh* mesh, double scale);

}  // namespace lp
