#include "estimation/truth.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <nlohmann/json.hpp>

#include "common/color.h"
#include "common/error.h"

namespace lp {
using nlohmann::json;

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const double c = std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0);
  return std::acos(c) * 180.0 / 3.14159265358979323846;
}

namespace {

json ParseJson(const std::string& text, const std::string& name) {
  try {
    return json::parse(text);
  } catch (const json::exception& e) {
    throw InputError(name, std::string("malformed JSON: ") + e.what());
  }
}

Eigen::Vector3f TruthPoint(const json& v, const std::string& name) {
  if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number())
    throw InputError(name, "an emitter's corners and normal must be 3 numbers each");
  return Eigen::Vector3f(v[0].get<float>(), v[1].get<float>(), v[2].get<float>());
}

/// One emitter's quads into `mesh` (two triangles each) and their normals.
void AddTruthQuad(const json& q, const std::string& name, Mesh* mesh, std::vector<int>* triangles,
                  std::vector<Eigen::Vector3f>* facing) {
  if (!q.contains("corners") || !q["corners"].is_array() || q["corners"].size() != 4 || !q.contains("normal"))
    throw InputError(name, "an emitter's quad needs 4 \"corners\" and a \"normal\"");
  const int first = static_cast<int>(mesh->positions.size());
  for (const json& p : q["corners"]) mesh->positions.push_back(TruthPoint(p, name));
  mesh->albedo.resize(mesh->positions.size(), Eigen::Vector3f::Zero());
  const Eigen::Vector3f n = TruthPoint(q["normal"], name);
  for (const Eigen::Vector3i& t : {Eigen::Vector3i(0, 1, 2), Eigen::Vector3i(0, 2, 3)}) {
    triangles->push_back(static_cast<int>(mesh->triangles.size()));
    mesh->triangles.push_back(t + Eigen::Vector3i::Constant(first));
    facing->push_back(n);
  }
}

}  // namespace

std::vector<EmitterLight> ParseTruthEmitters(const std::string& text, const std::string& name) {
  const json j = ParseJson(text, name);
  std::vector<EmitterLight> out;
  if (!j.is_object() || !j.contains("emitters")) return out;
  if (!j["emitters"].is_array()) throw InputError(name, "\"emitters\" must be a list");
  for (const json& e : j["emitters"]) {
    Mesh mesh;
    std::vector<int> triangles;
    std::vector<Eigen::Vector3f> facing;
    if (e.contains("quads") && e["quads"].is_array())
      for (const json& q : e["quads"]) AddTruthQuad(q, name, &mesh, &triangles, &facing);
    else
      AddTruthQuad(e, name, &mesh, &triangles, &facing);
    if (!e.contains("radiance")) throw InputError(name, "an emitter needs its \"radiance\"");
    EmitterLight light;
    light.id = static_cast<int>(out.size());
    light.shape = MakeEmitterShape(mesh, triangles, facing);
    light.radiance = TruthPoint(e["radiance"], name).cast<double>();
    out.push_back(light);
  }
  return out;
}

std::vector<TruthLight> ParseTruthLights(const std::string& text, const std::string& name) {
  const json j = ParseJson(text, name);
  if (!j.is_object() || !j.contains("lights") || !j["lights"].is_array())
    throw InputError(name, "expected an object with a \"lights\" array");
  const auto vec3 = [&](const json& v, const char* what) {
    if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number())
      throw InputError(name, std::string("light \"") + what + "\" must be 3 numbers");
    const Eigen::Vector3d out(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
    if (!out.allFinite()) throw InputError(name, std::string("light ") + what + " is not finite");
    return out;
  };
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  if (j.contains("scene_bbox") && j["scene_bbox"].is_object() && j["scene_bbox"].contains("centre"))
    centre = vec3(j["scene_bbox"]["centre"], "scene_bbox centre");
  std::vector<TruthLight> out;
  for (const json& l : j["lights"]) {
    if (!l.is_object() || !(l.contains("direction") || l.contains("position")))
      continue;  // e.g. a map without a dominant direction
    TruthLight t;
    t.type = l.value("type", "");
    if (l.contains("position")) t.position = vec3(l["position"], "position");
    t.direction = l.contains("direction") ? vec3(l["direction"], "direction") : Eigen::Vector3d(*t.position - centre);
    if (t.direction.norm() == 0) throw InputError(name, "light direction is not finite");
    t.direction.normalize();
    const char* keys[] = {"rgb_power", "rgb", "rgb_radiance"};
    bool weighed = false;
    for (const char* k : keys)
      if (l.contains(k) && l[k].is_array() && l[k].size() == 3 && l[k][0].is_number()) {
        t.weight = Luminance(l[k][0].get<double>(), l[k][1].get<double>(), l[k][2].get<double>());
        weighed = true;
      }
    if (!weighed && t.position && l.contains("radiant_intensity_rgb_W_per_sr")) {
      const Eigen::Vector3d I = vec3(l["radiant_intensity_rgb_W_per_sr"], "radiant_intensity_rgb_W_per_sr");
      t.weight = Luminance(I.x(), I.y(), I.z()) / std::max(1e-12, (*t.position - centre).squaredNorm());
    }
    if (l.contains("weight") && l["weight"].is_number()) t.weight = l["weight"].get<double>();
    out.push_back(t);
  }
  return out;
}

void CentreTruthLights(std::vector<TruthLight>* truth, const Eigen::Vector3d& centre) {
  for (TruthLight& t : *truth)
    if (t.position && (*t.position - centre).norm() > 0) t.direction = (*t.position - centre).normalized();
}

std::vector<Eigen::Vector3d> DominantDirections(const EnvMap& env, const std::vector<double>& lambda, int count,
                                                double separation_deg) {
  const int L = env.size();
  std::vector<double> power(L);
  for (int j = 0; j < L; ++j)
    power[j] = std::max(0.0, Luminance(lambda[3 * j], lambda[3 * j + 1], lambda[3 * j + 2])) * env.solid_angle(j);
  constexpr double kDeg = 3.14159265358979323846 / 180;
  // Gaussian kernel of half the separation on the sphere: exp((cos t - 1) / s^2) ~ exp(-t^2 / 2s^2),
  // cut at 3 s.
  const double s = separation_deg / 2 * kDeg, inv_s2 = 1 / (s * s), cut = std::cos(std::min(3 * s, 3.14159));
  const auto kernel = [&](double c) { return c >= cut ? std::exp((c - 1) * inv_s2) : 0.0; };
  const double far = std::cos(separation_deg * kDeg);
  std::vector<Eigen::Vector3d> out;
  for (int k = 0; k < count; ++k) {
    // Start from the cell whose kernel gathers the most remaining power, at least the
    // separation from the lights already found.
    int best = -1;
    double best_gathered = 0;
    for (int i = 0; i < L; ++i) {
      bool apart = true;
      for (const auto& d : out) apart = apart && env.direction(i).dot(d) <= far;
      if (!apart) continue;
      double g = 0;
      for (int j = 0; j < L; ++j)
        if (power[j] > 0) g += power[j] * kernel(env.direction(i).dot(env.direction(j)));
      if (g > best_gathered) best_gathered = g, best = i;
    }
    if (best < 0) break;
    // Mean shift: move to the kernel-weighted mean direction until it stays.
    Eigen::Vector3d c = env.direction(best);
    for (int it = 0; it < 100; ++it) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int j = 0; j < L; ++j)
        if (power[j] > 0) sum += power[j] * kernel(c.dot(env.direction(j))) * env.direction(j);
      if (!(sum.norm() > 0)) break;
      const Eigen::Vector3d next = sum.normalized();
      const bool settled = next.dot(c) > std::cos(1e-4 * kDeg);
      c = next;
      if (settled) break;
    }
    out.push_back(c);
    // The cells within the separation belong to this light.
    for (int j = 0; j < L; ++j)
      if (env.direction(j).dot(c) > far) power[j] = 0;
  }
  return out;
}

std::vector<Eigen::Vector3d> DominantDirections(const EnvMap& env, const std::vector<double>& lambda,
                                                const std::vector<DirectionalLight>& suns, int count) {
  if (suns.empty()) return DominantDirections(env, lambda, count);
  std::vector<std::pair<double, Eigen::Vector3d>> lights;
  const double near = std::cos(30 * 3.14159265358979323846 / 180);
  for (const Eigen::Vector3d& d : DominantDirections(env, lambda, count)) {
    double e = 0;
    for (int j = 0; j < env.size(); ++j)
      if (env.direction(j).dot(d) > near)
        e += std::max(0.0, Luminance(lambda[3 * j], lambda[3 * j + 1], lambda[3 * j + 2])) * env.solid_angle(j);
    lights.emplace_back(e, d);
  }
  for (const DirectionalLight& s : suns)
    lights.emplace_back(Luminance(s.irradiance.x(), s.irradiance.y(), s.irradiance.z()), s.direction);
  std::stable_sort(lights.begin(), lights.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<Eigen::Vector3d> out;
  for (int k = 0; k < std::min<int>(count, static_cast<int>(lights.size())); ++k) out.push_back(lights[k].second);
  return out;
}

double DominantAngularErrorDeg(const EnvMap& env, const std::vector<double>& lambda,
                               const std::vector<TruthLight>& truth) {
  if (truth.empty()) return std::nan("");
  std::vector<TruthLight> sorted = truth;
  std::sort(sorted.begin(), sorted.end(), [](const auto& a, const auto& b) { return a.weight > b.weight; });
  const int n = std::min<int>(2, static_cast<int>(sorted.size()));
  const auto est = DominantDirections(env, lambda, n);
  if (est.empty()) return 180.0;
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    double best = 180;
    for (const auto& d : est) best = std::min(best, AngleDeg(d, sorted[i].direction));
    sum += best;
  }
  return sum / n;
}

double DominantAngularErrorDeg(const EnvMap& env, const std::vector<double>& lambda,
                               const std::vector<PointLight>& points, const Eigen::Vector3d& centre,
                               const std::vector<TruthLight>& truth, const std::vector<DirectionalLight>& suns) {
  if ((points.empty() && suns.empty()) || truth.empty()) return DominantAngularErrorDeg(env, lambda, truth);
  std::vector<TruthLight> sorted = truth;
  std::sort(sorted.begin(), sorted.end(), [](const auto& a, const auto& b) { return a.weight > b.weight; });
  const int n = std::min<int>(2, static_cast<int>(sorted.size()));
  // The estimate's lights with the irradiance each gives at the centre.
  std::vector<std::pair<double, Eigen::Vector3d>> lights;
  const double near = std::cos(30 * 3.14159265358979323846 / 180);
  for (const Eigen::Vector3d& d : DominantDirections(env, lambda, 2)) {
    double e = 0;
    for (int j = 0; j < env.size(); ++j)
      if (env.direction(j).dot(d) > near)
        e += std::max(0.0, Luminance(lambda[3 * j], lambda[3 * j + 1], lambda[3 * j + 2])) * env.solid_angle(j);
    lights.emplace_back(e, d);
  }
  for (const PointLight& p : points) {
    const Eigen::Vector3d r = p.position - centre;
    if (!(r.norm() > 0)) continue;
    lights.emplace_back(Luminance(p.intensity.x(), p.intensity.y(), p.intensity.z()) / r.squaredNorm(),
                        r.normalized());
  }
  for (const DirectionalLight& d : suns)
    lights.emplace_back(Luminance(d.irradiance.x(), d.irradiance.y(), d.irradiance.z()), d.direction);
  std::sort(lights.begin(), lights.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  if (lights.empty()) return 180.0;
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    double best = 180;
    for (int k = 0; k < std::min<int>(n, static_cast<int>(lights.size())); ++k)
      best = std::min(best, AngleDeg(lights[k].second, sorted[i].direction));
    sum += best;
  }
  return sum / n;
}

double WorstPositionError(const std::vector<PointLight>& points, const std::vector<TruthLight>& truth,
                          const Eigen::Vector3d& centre, double far_distance, double* share) {
  double worst = std::nan(""), worst_share = std::nan("");
  for (const TruthLight& t : truth) {
    const double distance = t.position ? (*t.position - centre).norm() : 0.0;
    if (!t.position || !(distance < far_distance)) continue;
    double best = std::numeric_limits<double>::infinity();
    for (const PointLight& p : points) best = std::min(best, (p.position - *t.position).norm());
    worst = std::isnan(worst) ? best : std::max(worst, best);
    const double s = distance > 0 ? best / distance : std::numeric_limits<double>::infinity();
    worst_share = std::isnan(worst_share) ? s : std::max(worst_share, s);
  }
  if (share) *share = worst_share;
  return worst;
}

namespace {

/// The RMSE of `image` against `other` over the valid pixels, and `scale`'s mean there (both
/// over the same values); n = 0 without valid pixels.
struct RmseAndMean {
  double rmse = 0, mean = 0;
  std::int64_t n = 0;
};
RmseAndMean Rmse(const ImageRGB& image, const ImageRGB& other, const ImageRGB& scale,
                 const std::vector<std::uint8_t>& valid) {
  LP_CHECK(image.width == other.width && image.height == other.height, "image size mismatch");
  double se = 0, sum = 0;
  std::int64_t n = 0;
  for (std::size_t p = 0; p < valid.size(); ++p) {
    if (!valid[p]) continue;
    for (int c = 0; c < 3; ++c) {
      const double d = double(image.data[3 * p + c]) - other.data[3 * p + c];
      se += d * d;
      sum += scale.data[3 * p + c];
    }
    n += 3;
  }
  if (n == 0) return {};
  return {std::sqrt(se / n), sum / n, n};
}

}  // namespace

double RelativeImageRmse(const ImageRGB& image, const ImageRGB& reference, const std::vector<std::uint8_t>& valid) {
  const RmseAndMean e = Rmse(image, reference, reference, valid);
  if (e.n == 0 || !(e.mean > 0)) return std::nan("");
  return e.rmse / e.mean;
}

double RelativeImageRmseBeyondNoise(const ImageRGB& image, const ImageRGB& image2, const ImageRGB& reference,
                                    const ImageRGB& reference2, const std::vector<std::uint8_t>& valid,
                                    double* noise_image, double* noise_reference) {
  // Every RMSE over the reference's mean; each pair's difference is its noise times sqrt 2.
  const double error = RelativeImageRmse(image, reference, valid);
  const auto noise = [&](const ImageRGB& a, const ImageRGB& b) {
    const RmseAndMean e = Rmse(a, b, reference, valid);
    return e.n == 0 || !(e.mean > 0) ? std::nan("") : e.rmse / e.mean / std::sqrt(2.0);
  };
  const double ni = noise(image, image2), nr = noise(reference, reference2);
  if (noise_image) *noise_image = ni;
  if (noise_reference) *noise_reference = nr;
  if (!std::isfinite(error) || !std::isfinite(ni) || !std::isfinite(nr)) return std::nan("");
  return std::sqrt(std::max(0.0, error * error - ni * ni - nr * nr));
}

double EnvMapRelativeError(const EnvMap& env, const std::vector<double>& lambda, const std::vector<double>& truth,
                           const std::vector<std::uint8_t>& left_out) {
  if (truth.empty()) return std::nan("");
  LP_CHECK(lambda.size() == truth.size() && truth.size() == 3 * static_cast<std::size_t>(env.size()),
           "map size mismatch");
  double num = 0, den = 0;
  for (int j = 0; j < env.size(); ++j) {
    if (!left_out.empty() && left_out[j]) continue;
    for (int c = 0; c < 3; ++c) {
      const double d = lambda[3 * j + c] - truth[3 * j + c];
      num += env.solid_angle(j) * d * d;
      den += env.solid_angle(j) * truth[3 * j + c] * truth[3 * j + c];
    }
  }
  return den > 0 ? std::sqrt(num / den) : std::nan("");
}

}  // namespace lp
