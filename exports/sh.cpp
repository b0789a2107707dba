#include "exports/sh.h"

#include <algorithm>
#include <cmath>

#include <nlohmann/json.hpp>

#include "common/atomic_file.h"
#include "estimation/envmap.h"
#include "estimation/lights_file.h"
#include "exports/axes.h"

namespace lp {
namespace fs = std::filesystem;
using nlohmann::json;
namespace {
constexpr double kPi = 3.14159265358979323846;

double Luminance(const Eigen::Vector3d& c) { return 0.2126 * c.x() + 0.7152 * c.y() + 0.0722 * c.z(); }

/// Calls f(direction in the world frame, radiance, solid angle) for `sub` x `sub` points of
/// every pixel of the map with a non-zero value.
template <class F>
void ForEachSample(const ImageRGB& map, const Eigen::Vector3d& up, int sub, F&& f) {
  const EnvMap frame(2, up);
  const double dphi = 2 * kPi / (map.width * sub), dtheta = kPi / (map.height * sub);
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x < map.width; ++x) {
      const float* p = map.at(x, y);
      if (p[0] == 0 && p[1] == 0 && p[2] == 0) continue;
      const Eigen::Vector3d L(p[0], p[1], p[2]);
      for (int j = 0; j < sub; ++j) {
        // Two-point Gauss-Legendre in z = cos(theta) over the band (exact for the basis' powers
        // of z up to 3), the midpoint in azimuth (exact for its cos/sin of 2 phi over a row).
        const double z0 = std::cos((y * sub + j) * dtheta), z1 = std::cos((y * sub + j + 1) * dtheta);
        const double omega = 0.5 * (z0 - z1) * dphi, mid = 0.5 * (z0 + z1), half = 0.5 * (z0 - z1) / std::sqrt(3.0);
        for (double z : {mid - half, mid + half})
          for (int i = 0; i < sub; ++i)
            f(frame.FromSpherical(std::acos(std::clamp(z, -1.0, 1.0)), (x * sub + i + 0.5) * dphi), L, omega);
      }
    }
}

json Coefficients(const Sh9& sh) {
  json a = json::array();
  for (const auto& c : sh) a.push_back({c.x(), c.y(), c.z()});
  return a;
}

json Vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

/// The light an AR engine draws as its one shadow-casting light: the strongest directional
/// light, else the map's brightest region (pixels within 20 degrees of its brightest pixel,
/// their irradiance on a surface facing their mean direction).
struct MainLight {
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d irradiance = Eigen::Vector3d::Zero();
  int directional_index = -1;  ///< which directional light it is; -1: from the map
};

MainLight FindMainLight(const ExportScene& s) {
  MainLight m;
  double best = -1;
  const std::vector<DirectionalLight> suns = OfKind<DirectionalLight>(s.lights);
  for (std::size_t k = 0; k < suns.size(); ++k) {
    const double e = Luminance(suns[k].irradiance);
    if (e > best) {
      best = e;
      m.direction = suns[k].direction.normalized();
      m.irradiance = suns[k].irradiance;
      m.directional_index = static_cast<int>(k);
    }
  }
  if (m.directional_index >= 0 || s.environment.height == 0) return m;
  Eigen::Vector3d peak = s.up;
  double peak_l = -1;
  ForEachSample(s.environment, s.up, 1, [&](const Eigen::Vector3d& d, const Eigen::Vector3d& L, double) {
    if (Luminance(L) > peak_l) peak_l = Luminance(L), peak = d;
  });
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  const double cos20 = std::cos(20 * kPi / 180);
  ForEachSample(s.environment, s.up, 1, [&](const Eigen::Vector3d& d, const Eigen::Vector3d& L, double omega) {
    if (d.dot(peak) >= cos20) mean += Luminance(L) * omega * d;
  });
  m.direction = mean.norm() > 0 ? mean.normalized() : peak;
  ForEachSample(s.environment, s.up, 1, [&](const Eigen::Vector3d& d, const Eigen::Vector3d& L, double omega) {
    if (d.dot(peak) >= cos20) m.irradiance += L * omega * std::max(0.0, d.dot(m.direction));
  });
  return m;
}

/// Calls f(direction, radiance x solid angle) for each piece of the emitter's triangles seen
/// from `at` on its emitting side (each triangle in 16 pieces, each at its own direction).
template <class F>
void ForEachEmitterPiece(const EmitterLight& light, const Eigen::Vector3d& at, F&& f) {
  if (!light.shape) return;
  constexpr int kSplit = 4;
  const EmitterShape& s = *light.shape;
  for (std::size_t t = 0; t < s.a.size(); ++t) {
    const Eigen::Vector3d a = s.a[t].cast<double>() - at, b = s.b[t].cast<double>() - at, c = s.c[t].cast<double>() - at;
    if (s.normal[t].cast<double>().dot((a + b + c) / 3) >= 0) continue;  // seen from behind: dark
    const auto corner = [&](int i, int j) { return a + (b - a) * (double(i) / kSplit) + (c - a) * (double(j) / kSplit); };
    for (int i = 0; i < kSplit; ++i)
      for (int j = 0; i + j < kSplit; ++j)
        for (int flip = 0; flip < (i + j + 1 < kSplit ? 2 : 1); ++flip) {
          const Eigen::Vector3d p = flip ? corner(i + 1, j + 1) : corner(i, j), q = corner(i + 1, j), r = corner(i, j + 1);
          f(((p + q + r) / 3).normalized(), Eigen::Vector3d(light.radiance * TriangleSolidAngle(p, q, r)));
        }
  }
}

/// The order-2 irradiance's relative error against the exact one over normals spread evenly
/// over the sphere (Fibonacci points): RMS and largest, relative to the largest irradiance.
std::pair<double, double> TruncationError(const ExportScene& s, const std::vector<DirectionalLight>& in_sh,
                                          const Eigen::Vector3d& centre, const Sh9& irradiance) {
  constexpr int kNormals = 256;
  double top = 0, sum2 = 0, worst = 0;
  std::vector<double> err;
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> samples;  // direction, radiance x solid angle
  if (s.environment.height)
    ForEachSample(s.environment, s.up, 1, [&](const Eigen::Vector3d& d, const Eigen::Vector3d& L, double omega) {
      samples.emplace_back(d, L * omega);
    });
  for (const EmitterLight& e : OfKind<EmitterLight>(s.lights))
    ForEachEmitterPiece(e, centre, [&](const Eigen::Vector3d& d, const Eigen::Vector3d& power) { samples.emplace_back(d, power); });
  for (int k = 0; k < kNormals; ++k) {
    const double z = 1 - (2 * k + 1.0) / kNormals, r = std::sqrt(1 - z * z), phi = k * kPi * (3 - std::sqrt(5.0));
    const Eigen::Vector3d n(r * std::cos(phi), r * std::sin(phi), z);
    Eigen::Vector3d exact = Eigen::Vector3d::Zero();
    for (const auto& [d, power] : samples) exact += power * std::max(0.0, n.dot(d));
    for (const DirectionalLight& d : in_sh) exact += d.irradiance * std::max(0.0, n.dot(d.direction.normalized()));
    const double e = Luminance(EvaluateSh(irradiance, n)) - Luminance(exact);
    top = std::max(top, Luminance(exact));
    err.push_back(std::abs(e));
  }
  if (top <= 0) return {0, 0};
  for (double e : err) sum2 += e * e, worst = std::max(worst, e);
  return {std::sqrt(sum2 / kNormals) / top, worst / top};
}

}  // namespace

std::array<double, 9> ShBasis(const Eigen::Vector3d& d) {
  const double x = d.x(), y = d.y(), z = d.z();
  return {0.282094791773878, 0.488602511902920 * y, 0.488602511902920 * z, 0.488602511902920 * x,
          1.092548430592079 * x * y, 1.092548430592079 * y * z, 0.315391565252520 * (3 * z * z - 1),
          1.092548430592079 * x * z, 0.546274215296040 * (x * x - y * y)};
}

Sh9 ProjectMap(const ImageRGB& map, const Eigen::Vector3d& up, const Eigen::Matrix3d& frame_from_world, int sub) {
  Sh9 sh;
  sh.fill(Eigen::Vector3d::Zero());
  ForEachSample(map, up, sub, [&](const Eigen::Vector3d& d, const Eigen::Vector3d& L, double omega) {
    const auto y = ShBasis(frame_from_world * d);
    for (int i = 0; i < 9; ++i) sh[i] += L * (y[i] * omega);
  });
  return sh;
}

void AddDirectional(const DirectionalLight& light, const Eigen::Matrix3d& frame_from_world, Sh9* sh) {
  const auto y = ShBasis(frame_from_world * light.direction.normalized());
  for (int i = 0; i < 9; ++i) (*sh)[i] += light.irradiance * y[i];
}

double TriangleSolidAngle(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const double la = a.norm(), lb = b.norm(), lc = c.norm();
  const double numerator = a.dot(b.cross(c));
  const double denominator = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
  return std::abs(2 * std::atan2(numerator, denominator));
}

void AddEmitter(const EmitterLight& light, const Eigen::Vector3d& at, const Eigen::Matrix3d& frame_from_world, Sh9* sh) {
  ForEachEmitterPiece(light, at, [&](const Eigen::Vector3d& d, const Eigen::Vector3d& power) {
    const auto y = ShBasis(frame_from_world * d);
    for (int k = 0; k < 9; ++k) (*sh)[k] += power * y[k];
  });
}

Sh9 IrradianceFromRadiance(const Sh9& radiance) {
  static const double a[9] = {kPi, 2 * kPi / 3, 2 * kPi / 3, 2 * kPi / 3, kPi / 4, kPi / 4, kPi / 4, kPi / 4, kPi / 4};
  Sh9 e;
  for (int i = 0; i < 9; ++i) e[i] = a[i] * radiance[i];
  return e;
}

Eigen::Vector3d EvaluateSh(const Sh9& sh, const Eigen::Vector3d& d) {
  const auto y = ShBasis(d);
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  for (int i = 0; i < 9; ++i) v += sh[i] * y[i];
  return v;
}

Eigen::Vector3d MapIrradiance(const ImageRGB& map, const Eigen::Vector3d& up, const Eigen::Vector3d& n, int sub) {
  Eigen::Vector3d e = Eigen::Vector3d::Zero();
  ForEachSample(map, up, sub, [&](const Eigen::Vector3d& d, const Eigen::Vector3d& L, double omega) {
    const double c = n.dot(d);
    if (c > 0) e += L * (c * omega);
  });
  return e;
}

namespace {

/// lighting.json's point and directional lights by value: as lights.json writes them (with
/// their uncertainty where the estimate gave one), each position, direction and covariance
/// also in the y-up frame (G v, G C G^T; a covariance with an unknown entry as it is).
void AddLightsByValue(const ExportScene& s, const Eigen::Matrix3d& G, json* out) {
  const json file = json::parse(LightsJson({"", s.lights, s.uncertainty, {}}));
  const auto turned_covariance = [&](const json& c) {
    Eigen::Matrix3d m;
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) {
        if (c[r][k].is_null()) return c;
        m(r, k) = c[r][k].get<double>();
      }
    m = G * m * G.transpose();
    return json{Vec(m.row(0)), Vec(m.row(1)), Vec(m.row(2))};
  };
  ForEachKind([&](const auto& kind) {
    const char* key = LightsKey(kind);
    (*out)[key] = file[key];
    for (json& l : (*out)[key]) {
      for (const std::string v : {"position", "direction"})
        if (l.contains(v)) l[v + "_y_up"] = Vec(G * Eigen::Vector3d(l[v][0], l[v][1], l[v][2]));
      for (const std::string c : {"position_covariance", "direction_covariance"})
        if (l.contains(c)) l[c + "_y_up"] = turned_covariance(l[c]);
    }
  });
}

}  // namespace

std::vector<std::string> WriteShExport(const ExportScene& s, const fs::path& dir) {
  const ExportAxes axes(s.up);
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity(), G = axes.gltf_from_world;
  const MainLight main = FindMainLight(s);
  // The SH hold the map and every directional light but the main light when it is one (an
  // engine adds that one itself); a main light taken from the map is a summary of what the SH hold.
  std::vector<DirectionalLight> in_sh;
  const std::vector<DirectionalLight> suns = OfKind<DirectionalLight>(s.lights);
  // Glowing surfaces as seen from the centre of the mesh's bounding box.
  Eigen::Vector3f low, high;
  MeshBounds(s.mesh, &low, &high);
  const Eigen::Vector3d centre = s.mesh.triangles.empty() ? Eigen::Vector3d::Zero() : Eigen::Vector3d(0.5 * (low + high).cast<double>());
  for (std::size_t k = 0; k < suns.size(); ++k)
    if (static_cast<int>(k) != main.directional_index) in_sh.push_back(suns[k]);
  auto radiance_in = [&](const Eigen::Matrix3d& frame) {
    Sh9 sh;
    if (s.environment.height) sh = ProjectMap(s.environment, s.up, frame);
    else sh.fill(Eigen::Vector3d::Zero());
    for (const DirectionalLight& d : in_sh) AddDirectional(d, frame, &sh);
    for (const EmitterLight& e : OfKind<EmitterLight>(s.lights)) AddEmitter(e, centre, frame, &sh);
    return sh;
  };
  const Sh9 radiance = radiance_in(I), radiance_y_up = radiance_in(G);
  const Sh9 irradiance = IrradianceFromRadiance(radiance);
  const auto [rms, worst] = TruncationError(s, in_sh, centre, irradiance);
  json j;
  j["frame"] = {
      {"world", "the scene bundle's world frame"},
      {"up", Vec(s.up)},
      {"y_up_from_world", {Vec(G.row(0)), Vec(G.row(1)), Vec(G.row(2))}},
      {"basis", "real spherical harmonics to order 2, orthonormal over the sphere, of a unit direction (x, y, z): "
                "0.282095; 0.488603 y; 0.488603 z; 0.488603 x; 1.092548 xy; 1.092548 yz; 0.315392 (3z^2 - 1); "
                "1.092548 xz; 0.546274 (x^2 - y^2)"},
      {"radiance", "sh9_radiance[i] = integral of L(w) Y_i(w) dw (image units: the fitted images' radiance)"},
      {"irradiance", "sh9_irradiance[i] = sh9_radiance[i] x (pi, 2pi/3, 2pi/3, 2pi/3, pi/4 x 5): the irradiance "
                     "E(n) = sum_i sh9_irradiance[i] Y_i(n) of a surface with normal n; a Lambertian surface of "
                     "albedo rho shows rho / pi x E(n)"},
      {"contents", main.directional_index >= 0
                       ? "the map, the directional lights except the main light, and the emitters as seen from the "
                         "centre of the mesh's bounding box (point lights: by value only)"
                       : "the map, every directional light and the emitters as seen from the centre of the mesh's "
                         "bounding box (the main light summarizes the map's brightest region; point lights: by value "
                         "only)"}};
  j["sh9_radiance"] = Coefficients(radiance);
  j["sh9_irradiance"] = Coefficients(irradiance);
  j["y_up"] = {{"sh9_radiance", Coefficients(radiance_y_up)},
               {"sh9_irradiance", Coefficients(IrradianceFromRadiance(radiance_y_up))}};
  j["sh9_irradiance_error"] = {
      {"rms", rms}, {"max", worst},
      {"what", "order-2 irradiance against the exact irradiance of what the coefficients hold, over 256 normals "
               "spread evenly over the sphere, relative to the largest (luminance)"}};
  Eigen::Vector3d colour;
  const double m = SplitColour(main.irradiance, &colour);
  j["main_light"] = {{"source", main.directional_index >= 0 ? "directional_light" : "map"},
                     {"direction", Vec(main.direction)},
                     {"direction_y_up", Vec(G * main.direction)},
                     {"color", Vec(colour)},
                     {"intensity", m},
                     {"what", "direction towards the light; intensity x color = its irradiance on a surface facing it"}};
  AddLightsByValue(s, G, &j);
  WriteTextAtomically(dir / "lighting.json", j.dump(2) + "\n");
  return {"lighting.json"};
}

}  // namespace lp
