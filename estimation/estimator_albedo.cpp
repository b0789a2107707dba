#include "estimation/estimator_impl.h"

namespace lp::detail {

// Albedo refinement: the reconstruction's albedo is the colour seen, flattened per
// segment of one chromaticity, so each segment's mean still holds its mean shading (and
// two surfaces of one chromaticity share one albedo). Divided by the estimate's
// irradiance, the colour seen is the albedo the estimate implies; segmented again (now
// a brightness step is a material's) it is the albedo the next rounds are solved under.
AlbedoLeftOut Estimator::AlbedoLeftOutByOptions() const {
  if (opt_.albedo_passes <= 0) return AlbedoLeftOut::kNoPasses;
  if (bundle_.mesh.shaded.size() != bundle_.mesh.positions.size()) return AlbedoLeftOut::kKnownAlbedo;
  return AlbedoLeftOut::kRefined;
}

bool Estimator::AlbedoRefinable() {
  if (const AlbedoLeftOut why = AlbedoLeftOutByOptions(); why != AlbedoLeftOut::kRefined) res_.albedo_left_out = why;
  if (res_.albedo_left_out != AlbedoLeftOut::kRefined) return false;
  mesh_ = bundle_.mesh;
  return true;
}

/// Per vertex of the bundle's mesh, the mean of `values` over the vertices of its cluster
/// whose normals are within 37 degrees of its own (a box's edge keeps its faces apart); a
/// vertex with none keeps its own value.
std::vector<float> Estimator::OverClusters(const std::vector<float>& values) const {
  if (cluster_.empty()) return values;
  const Mesh& full = bundle_.mesh;
  std::vector<int> start(scene_->mesh().positions.size() + 1, 0), members(cluster_.size());
  for (int c : cluster_)
    if (c >= 0) ++start[c + 1];
  for (std::size_t c = 1; c < start.size(); ++c) start[c] += start[c - 1];
  std::vector<int> fill(start.begin(), start.end() - 1);
  for (std::size_t v = 0; v < cluster_.size(); ++v)
    if (cluster_[v] >= 0) members[fill[cluster_[v]]++] = static_cast<int>(v);
  std::vector<float> out(values);
  ParallelForChunks(0, cluster_.size(), 1024, [&](std::size_t b, std::size_t e) {
    for (std::size_t v = b; v < e; ++v) {
      if (cluster_[v] < 0) continue;
      double sum = 0;
      int n = 0;
      // At most 64 members each (a mesh far finer than the pixels would make this quadratic).
      const int first = start[cluster_[v]], size = start[cluster_[v] + 1] - first, step = std::max(1, size / 64);
      for (int k = first; k < first + size; k += step)
        if (full.normals[members[k]].dot(full.normals[v]) > 0.8f) {
          sum += values[members[k]];
          ++n;
        }
      if (n > 0) out[v] = static_cast<float>(sum / n);
    }
  });
  return out;
}

/// The traced mesh under the albedo of `full` (the bundle's mesh): each cluster its
/// vertices' mean weighted by `irradiance` (what each adds to the light the cluster sends:
/// a vertex in the dark, whose de-lit albedo is least sure, adds least).
Mesh Estimator::WithAlbedoOf(const Mesh& full, const std::vector<float>& irradiance) const {
  if (cluster_.empty()) return full;
  Mesh traced = scene_->mesh();
  std::vector<Eigen::Vector3d> sum(traced.positions.size(), Eigen::Vector3d::Zero());
  std::vector<double> weight(traced.positions.size(), 0);
  for (std::size_t v = 0; v < cluster_.size(); ++v)
    if (cluster_[v] >= 0 && irradiance[v] > 0) {
      sum[cluster_[v]] += irradiance[v] * full.albedo[v].cast<double>();
      weight[cluster_[v]] += irradiance[v];
    }
  for (std::size_t i = 0; i < sum.size(); ++i)
    if (weight[i] > 0) traced.albedo[i] = (sum[i] / weight[i]).cast<float>();
  return traced;
}

/// Paths per vertex of the bundle's mesh for the albedo pass's irradiance: albedo_samples,
/// or on a clustered mesh about that many per cluster (at least 2 per vertex; OverClusters
/// averages them).
int Estimator::AlbedoPaths() const {
  if (cluster_.empty()) return opt_.albedo_samples;
  const double share = static_cast<double>(scene_->mesh().positions.size()) / bundle_.mesh.positions.size();
  return std::min(opt_.albedo_samples, std::max(2, static_cast<int>(std::lround(opt_.albedo_samples * share))));
}

/// The albedo pass's irradiance per vertex of the bundle's mesh, averaged over its clusters
/// (OverClusters). With albedo_noise > 0 every vertex has a quarter of them first, and a cluster's
/// vertices get twice their paths while its mean's relative standard error is above it,
/// up to AlbedoPaths() (a lit wall settles in a few paths, a corner in the shade takes them
/// all); with 0, AlbedoPaths() each.
std::vector<float> Estimator::AlbedoIrradiance(VertexRadiance* radiance, int pass) {
  const int most = AlbedoPaths();
  std::vector<std::uint8_t> more(mesh_.positions.size(), 1);
  int paths = 0;  // of each vertex still marked
  // First a quarter of the paths (about 8 a cluster: a standard error from fewer would say
  // too little too often), at least 2 a vertex.
  for (int step = opt_.albedo_noise > 0 ? std::min(most, std::max(2, most / 4)) : most; step > 0;) {
    for (int done = 0; done < step; done += 2) {  // Cancel is polled between steps
      radiance->Refine(std::min(2, step - done), more);
      CheckCancel();
    }
    paths += step;
    if (opt_.albedo_noise <= 0 || paths >= most) break;
    const std::size_t noisy = MarkNoisyClusters(*radiance, &more);
    const auto marked = std::count(more.begin(), more.end(), 1);
    Progress(Fmt("albedo pass %d: at %d paths a vertex %zu clusters (%lld vertices) above %.3g relative noise", pass,
                 paths, noisy, static_cast<long long>(marked), opt_.albedo_noise));
    step = noisy > 0 ? std::min(paths, most - paths) : 0;
  }
  double sum = 0;
  for (std::size_t v = 0; v < more.size(); ++v) sum += radiance->samples(v);
  res_.albedo_paths = more.empty() ? 0 : sum / more.size();
  return OverClusters(radiance->Irradiance());
}

/// Marks in `more` the vertices of the clusters (the traced mesh's vertices; each vertex its
/// own where the mesh is traced as it is) whose mean irradiance has a relative standard
/// error above albedo_noise, from their vertices' paths (a cluster's mean is its vertices'
/// mean); one without light yet is marked too (its few paths may have missed it). Returns
/// how many clusters it marked.
std::size_t Estimator::MarkNoisyClusters(const VertexRadiance& radiance, std::vector<std::uint8_t>* more) const {
  const std::vector<float> mean = radiance.Irradiance(), variance = radiance.IrradianceVariance();
  const auto cluster = [&](std::size_t v) { return cluster_.empty() ? static_cast<int>(v) : cluster_[v]; };
  const std::size_t clusters = cluster_.empty() ? mean.size() : scene_->mesh().positions.size();
  std::vector<double> sum(clusters, 0), var(clusters, 0);
  std::vector<int> members(clusters, 0);
  for (std::size_t v = 0; v < mean.size(); ++v)
    if ((*more)[v] && cluster(v) >= 0 && radiance.samples(v) > 0) {
      sum[cluster(v)] += mean[v];
      var[cluster(v)] += variance[v];
      ++members[cluster(v)];
    }
  std::vector<std::uint8_t> noisy(clusters, 0);
  std::size_t count = 0;
  for (std::size_t c = 0; c < clusters; ++c)
    if (members[c] > 0 && (!(sum[c] > 0) || std::sqrt(var[c]) > opt_.albedo_noise * sum[c])) {  // sqrt(var/m²)/(sum/m)
      noisy[c] = 1;
      ++count;
    }
  for (std::size_t v = 0; v < more->size(); ++v) (*more)[v] = (*more)[v] && cluster(v) >= 0 && noisy[cluster(v)];
  return count;
}

bool Estimator::RefineAlbedo(int pass) {
  CheckCancel();
  Stopwatch as;
  int segments = -1;  // an estimate that lights nothing (warned in Conclude) has no irradiance
  std::vector<float> irradiance;
  std::vector<int> labels;
  if (res_.rendered_fraction >= 0.01) {
    Progress(Fmt("albedo pass %d: de-lighting %zu vertices (at most %d paths each)", pass, mesh_.positions.size(),
                 AlbedoPaths()));
    {
      // The bundle's mesh itself (a clustered mesh folds where a flat surface crosses a
      // cell's boundary, and a vertex there can sit behind its neighbours' triangles).
      std::unique_ptr<RayTracer> full;
      if (!cluster_.empty()) full = std::make_unique<RayTracer>(mesh_, TrianglesOnShapes(mesh_, res_.openings));
      VertexRadiance radiance(full ? *full : *scene_, env_, {lambda_, Lights()}, opt_.tracer.bounces,
                              opt_.tracer.seed * 7919 + pass);
      if (!portals_.empty()) radiance.SetPortals(portals_, kPortalShare);
      irradiance = AlbedoIrradiance(&radiance, pass);
      // The albedo's scale by the rule it was given before the rounds (--room-albedo), or
      // the colours' own when that is 0.
      segments = DelightAlbedo(&mesh_, irradiance, DelitAlbedoOptions(), res_.albedo_scale, opt_.room_albedo, &labels);
      if (segments >= 0 && stride_ > 1) UseStride(1, static_cast<int>(res_.rounds.size()) + 1);  // every pixel after it
      if (segments >= 0 && opt_.free_albedo) {
        row_segment_ = RowSegments(full ? *full : *scene_, labels);
        const auto free_rows = std::count_if(row_segment_.begin(), row_segment_.end(), [](int s) { return s >= 0; });
        Progress(Fmt("albedo pass %d: the lights' places fitted with the albedo of %d segments left free (%lld of %zu "
                     "rows)",
                     pass, segments, static_cast<long long>(free_rows), row_segment_.size()));
      }
    }  // before the scene it refers to is replaced
  }
  res_.albedo_seconds += as.Seconds();
  if (segments < 0) {
    if (res_.albedo_passes == 0) res_.albedo_left_out = AlbedoLeftOut::kNothingLit;
    Progress("albedo pass " + std::to_string(pass) + ": " + ToString(AlbedoLeftOut::kNothingLit) + "; albedo kept");
    return false;
  }
  res_.albedo_segments = segments;
  Mesh traced = WithAlbedoOf(mesh_, irradiance);
  const std::vector<std::uint8_t> open = TrianglesOnShapes(traced, res_.openings);  // (a window's opening stays one)
  scene_ = std::make_unique<RayTracer>(std::move(traced), open);
  columns_.clear();  // they saw the old albedo
  res_.albedo_passes = pass;
  Progress(Fmt("albedo pass %d: de-lit %zu vertices into %d segments in %.2f s", pass, mesh_.positions.size(),
               segments, as.Seconds()));
  return true;
}

std::vector<int> Estimator::RowSegments(const RayTracer& full, const std::vector<int>& labels) const {
  std::vector<std::pair<const View*, std::size_t>> pixels;  // the rows' pixels, in y_'s order
  for (const View& v : views_)
    for (std::size_t i = 0; i < v.valid.size(); ++i)
      if (v.valid[i]) pixels.emplace_back(&v, i);
  std::vector<int> out(pixels.size(), -1);
  const Mesh& mesh = full.mesh();
  ParallelForChunks(0, pixels.size(), 4096, [&](std::size_t b, std::size_t e) {
    for (std::size_t r = b; r < e; ++r) {
      const Camera& cam = pixels[r].first->camera;
      const std::size_t p = pixels[r].second;
      // (the pixel's centre: integer coordinates, as the tracer's jitter is around them)
      const double u = static_cast<double>(p % cam.width), v = static_cast<double>(p / cam.width);
      SurfacePoint hit;
      if (!full.Intersect(cam.center(), cam.RayDirection(u, v), &hit) || hit.triangle < 0) continue;
      // The triangle's vertex nearest the hit (its three are of one segment but at a border).
      const Eigen::Vector3i& t = mesh.triangles[hit.triangle];
      int nearest = t[0];
      for (int k = 1; k < 3; ++k)
        if ((mesh.positions[t[k]].cast<double>() - hit.position).squaredNorm() <
            (mesh.positions[nearest].cast<double>() - hit.position).squaredNorm())
          nearest = t[k];
      if (nearest < static_cast<int>(labels.size())) out[r] = labels[nearest];
    }
  });
  return out;
}

bool Estimator::Settled(const std::vector<Light>& before) {
  const std::vector<Light> now = Lights();
  // Each light against the nearest of its kind before (the lights' order may change), the
  // counts of each kind the same or it moved without measure.
  const auto nearest = [&](const Light& light) {
    double best = INFINITY;
    for (const Light& was : before) best = std::min(best, ShapeDistance(light, was, centre_));
    return best;
  };
  std::vector<int> count(std::variant_size_v<Light>, 0);  // of each kind, now less before
  for (const Light& light : now) ++count[light.index()];
  for (const Light& light : before) --count[light.index()];
  const bool same_counts = std::all_of(count.begin(), count.end(), [](int c) { return c == 0; });
  double moved = same_counts ? 0 : INFINITY;
  for (const Light& light : now) moved = std::max(moved, nearest(light));
  res_.albedo_last_move = moved;
  const bool settled = opt_.albedo_settle > 0 && moved <= opt_.albedo_settle;  // (no lamp nor sun: 0, settled)
  Progress(Fmt("albedo pass %d moved the lights by %.3g (a lamp: of its distance from the scene's centre; at most %.3g "
               "settles): %s",
               res_.albedo_passes, moved, opt_.albedo_settle,
               settled ? "settled" : res_.albedo_passes < opt_.albedo_passes ? "another pass" : "the last pass"));
  return settled;
}

}  // namespace lp::detail
