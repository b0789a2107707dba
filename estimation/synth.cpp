#include "estimation/synth.h"

#include <cmath>
#include <map>

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "common/color.h"
#include "common/error.h"
#include "common/parallel.h"
#include "common/rng.h"
#include "common/image_io.h"
#include "estimation/path_tracer.h"
#include "scene/ray_tracer.h"
#include "estimation/sampling.h"
#include "estimation/truth.h"

namespace lp {
namespace fs = std::filesystem;
using Eigen::Vector3d;
using Eigen::Vector3f;

Vector3d SphereLight::Radiance() const { return rgb_power / (4 * kPi * kPi * radius * radius); }

namespace {

Vector3f Srgb(int r, int g, int b) { return {SrgbToLinear(r / 255.f), SrgbToLinear(g / 255.f), SrgbToLinear(b / 255.f)}; }

/// Quad p0, p0+u, p0+u+v, p0+v with normal u x v, subdivided n x n.
Mesh Quad(const Vector3f& p0, const Vector3f& u, const Vector3f& v, const Vector3f& albedo, int n = 4) {
  Mesh m;
  const Vector3f nrm = u.cross(v).normalized();
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) {
      m.positions.push_back(p0 + u * (float(i) / n) + v * (float(j) / n));
      m.normals.push_back(nrm);
      m.albedo.push_back(albedo);
    }
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const int a = i * (n + 1) + j, b = (i + 1) * (n + 1) + j, c = (i + 1) * (n + 1) + j + 1, d = i * (n + 1) + j + 1;
      m.triangles.emplace_back(a, b, c);
      m.triangles.emplace_back(a, c, d);
    }
  return m;
}

/// Axis-aligned box standing on z = 0 (outward normals).
Mesh Box(const Vector3f& lo, const Vector3f& hi, const Vector3f& albedo) {
  const Vector3f d = hi - lo;
  const Vector3f X(d.x(), 0, 0), Y(0, d.y(), 0), Z(0, 0, d.z());
  Mesh m;
  m.Append(Quad(lo, Y, X, albedo, 1));                        // bottom (-z)
  m.Append(Quad(lo + Z, X, Y, albedo, 1));                    // top (+z)
  m.Append(Quad(lo, X, Z, albedo, 1));                        // -y
  m.Append(Quad(lo + Y, Z, X, albedo, 1));                    // +y
  m.Append(Quad(lo, Z, Y, albedo, 1));                        // -x
  m.Append(Quad(lo + X, Y, Z, albedo, 1));                    // +x
  return m;
}


/// Room corner: floor and two walls, two boxes and a sphere, varied albedos. Up = +z.
Mesh RoomCorner() {
  Mesh m;
  m.Append(Quad({0, 0, 0}, {3, 0, 0}, {0, 3, 0}, Srgb(180, 170, 160), 8));  // floor (+z)
  m.Append(Quad({0, 0, 0}, {0, 0, 2.2f}, {3, 0, 0}, Srgb(200, 200, 205), 8));  // wall y = 0 (+y)
  m.Append(Quad({0, 0, 0}, {0, 3, 0}, {0, 0, 2.2f}, Srgb(190, 175, 140), 8));  // wall x = 0 (+x)
  m.Append(Box({0.5f, 1.2f, 0}, {1.0f, 1.7f, 0.5f}, Srgb(160, 60, 50)));
  m.Append(Box({1.3f, 0.4f, 0}, {1.7f, 0.8f, 0.8f}, Srgb(60, 110, 170)));
  m.Append(UvSphere({1.5f, 1.5f, 0.35f}, 0.35f, Srgb(210, 210, 210)));
  return m;
}

Vector3d Direction(double azimuth_deg, double elevation_deg) {
  const double a = azimuth_deg * kPi / 180, e = elevation_deg * kPi / 180;
  return {std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e)};
}

/// Light of given colour at `distance` from `center` along `dir`, with power set so the
/// irradiance it gives at the centre (facing it) is `irradiance`.
SphereLight LightAt(const Vector3d& center, const Vector3d& dir, double distance, double radius,
                    const Vector3d& colour, double irradiance) {
  SphereLight l;
  l.position = center + distance * dir.normalized();
  l.radius = radius;
  l.rgb_power = colour * irradiance * 4 * kPi * distance * distance;
  return l;
}

/// Sphere-light direct lighting at `x`; returns T * sum over lights of rho/pi cos L / pdf.
Vector3d DirectFromSpheres(const RayTracer& scene, const SurfacePoint& hit, const Vector3d& off,
                           const std::vector<SphereLight>& lights, Rng& rng) {
  Vector3d sum = Vector3d::Zero();
  for (const SphereLight& l : lights) {
    const Vector3d to = l.position - hit.position;
    const double d2 = to.squaredNorm(), r2 = l.radius * l.radius;
    if (d2 <= r2) continue;
    const double d = std::sqrt(d2);
    const double cos_max = std::sqrt(1 - r2 / d2);
    const Vector3d w = SampleCone(to / d, cos_max, rng.Uniform(), rng.Uniform());
    const double cos_s = hit.shading.dot(w);
    if (cos_s <= 0 || hit.geometric.dot(w) <= 0) continue;
    const double b = w.dot(to);
    const double t = b - std::sqrt(std::max(0.0, r2 - (d2 - b * b)));
    if (scene.Occluded(off, w, t)) continue;
    const double pdf = 1.0 / (2 * kPi * (1 - cos_max));
    sum += hit.albedo.cwiseProduct(l.Radiance()) * (kInvPi * cos_s / pdf);
  }
  return sum;
}

}  // namespace

std::vector<ImageRGB> RenderSphereLights(const Mesh& mesh, const std::vector<View>& views,
                                         const SynthLighting& lighting, const SynthOptions& o) {
  RayTracer scene(mesh);
  const std::vector<SphereLight>& lights = lighting.lights;
  std::vector<ImageRGB> out;
  for (std::size_t v = 0; v < views.size(); ++v) {
    const Camera& cam = views[v].camera;
    ImageRGB img(cam.width, cam.height);
    ParallelFor(0, img.pixels(), [&](std::size_t p) {
      const int x = static_cast<int>(p % cam.width), y = static_cast<int>(p / cam.width);
      Vector3d acc = Vector3d::Zero();
      for (int s = 0; s < o.spp; ++s) {
        Rng rng(o.seed, v, p, s);
        Vector3d dir = cam.RayDirection(x + rng.Uniform() - 0.5, y + rng.Uniform() - 0.5);
        SurfacePoint hit;
        if (!scene.Intersect(cam.center(), dir, &hit)) continue;  // lights are not seen directly
        Vector3d T(1, 1, 1);
        for (int bounce = 0; bounce < o.bounces; ++bounce) {
          const Vector3d off = hit.position + hit.geometric * (4 * scene.epsilon());
          acc += T.cwiseProduct(DirectFromSpheres(scene, hit, off, lights, rng));
          const Vector3d w = SampleCosine(hit.shading, rng.Uniform(), rng.Uniform());
          T = T.cwiseProduct(hit.albedo);
          if (hit.geometric.dot(w) <= 0) break;
          SurfacePoint next;
          if (!scene.Intersect(off, w, &next)) {
            // Escaped: the sky (BSDF-sampled; the sphere lights are reached by NEE only).
            if (lighting.sky) acc += T.cwiseProduct(lighting.sky(w));
            break;
          }
          if (bounce >= 1) {
            const double q = std::min(0.95, T.maxCoeff());
            if (rng.Uniform() >= q) break;
            T /= q;
          }
          hit = next;
        }
      }
      float* px = img.at(x, y);
      for (int c = 0; c < 3; ++c) px[c] = static_cast<float>(acc[c] / o.spp);
    });
    out.push_back(std::move(img));
  }
  return out;
}

std::vector<std::pair<std::string, std::string>> SynthSceneList() {
  return {{"one-light", "room corner with boxes and a sphere, one spherical light 200 m away (5.7 degrees)"},
          {"two-light", "the same room, a warm key light and a cool fill light"},
          {"near-light", "the same room, one small light 0.6 m from the scene centre (far-light model under stress)"},
          {"sun-and-sky", "the same room under a 0.53-degree sun and a sky giving 1/1000 of its irradiance"},
          {"lamp-0.5m", "the same room, one 5 cm lamp 0.5 m from the scene centre"},
          {"lamp-1m", "the same room, one 5 cm lamp 1 m from the scene centre"},
          {"lamp-2m", "the same room, one 5 cm lamp 2 m from the scene centre"},
          {"lamp-4m", "the same room, one 5 cm lamp 4 m from the scene centre"},
          {"two-lamps", "the same room, a warm and a cool 5 cm lamp about 1.7 m from the scene centre"},
          {"lamp-and-sky", "the same room, a 5 cm lamp 1.5 m from the scene centre and a dim sky (1/20 of its irradiance)"},
          {"env-studio", "the same room lit by the real HDR map studio_small_03 (small bright softboxes)"},
          {"env-sunset", "the same room lit by the real HDR map venice_sunset (low sun, bright sky)"},
          {"frag115", "the real reconstructed mesh assets/mesh/frag_115.ply under one spherical light"}};
}

std::vector<double> TrueCellRadiance(const SynthLighting& lighting, const EnvMap& env) {
  if (!lighting.far) return {};
  std::vector<double> out(3 * env.size(), 0.0);
  if (lighting.equirect.pixels() > 0) out = env.FromEquirect(lighting.equirect, 256);
  if (lighting.sky) {
    const int s = 12;
    for (int j = 0; j < env.size(); ++j) {
      Vector3d sum = Vector3d::Zero();
      for (int a = 0; a < s; ++a)
        for (int b = 0; b < s; ++b) sum += lighting.sky(env.SampleInCell(j, (a + 0.5) / s, (b + 0.5) / s));
      for (int c = 0; c < 3; ++c) out[3 * j + c] += sum[c] / (s * s);
    }
  }
  for (const SphereLight& l : lighting.lights) {
    // All of the light's power lands in the cell of its centre direction (lights here are
    // far smaller than a cell): radiance times the solid angle it subtends, over the cell's.
    const Vector3d to = l.position - lighting.center;
    const double d = to.norm();
    const double omega = 2 * kPi * (1 - std::sqrt(std::max(0.0, 1 - l.radius * l.radius / (d * d))));
    const int j = env.Lookup(to);
    const Vector3d L = l.Radiance();
    for (int c = 0; c < 3; ++c) out[3 * j + c] += L[c] * omega / env.solid_angle(j);
  }
  return out;
}

namespace {

/// A smooth sky above the horizon (brighter towards the zenith, slightly blue), scaled so
/// its irradiance on a surface facing up is `irradiance`.
std::function<Vector3d(const Vector3d&)> Sky(const Vector3d& up, double irradiance) {
  // L(theta) = L0 (1 + 2 cos theta) / 3: E = 2 pi L0 (1/2 + 2/3) / 3 = 7 pi L0 / 9.
  const double L0 = irradiance * 9 / (7 * kPi);
  const Vector3d tint(0.8, 0.9, 1.2);
  return [=](const Vector3d& w) -> Vector3d {
    const double c = up.dot(w.normalized());
    if (c <= 0) return Vector3d::Zero();
    return tint * (L0 * (1 + 2 * c) / 3);
  };
}

/// The fitted view and, when asked, a held-out one (another viewpoint of the same scene).
std::vector<Camera> RoomCameras(const SynthOptions& o, const Vector3d& up) {
  std::vector<Camera> c = {Camera::LookAt({3.3, 2.9, 1.7}, {0.9, 0.9, 0.45}, up, o.width, o.height, 60)};
  if (o.held_out_views > 0) c.push_back(Camera::LookAt({1.1, 3.7, 1.4}, {1.2, 0.9, 0.4}, up, o.width, o.height, 60));
  return c;
}

}  // namespace

SceneBundle MakeSynthScene(const std::string& name, const SynthOptions& o, const fs::path& data_dir) {
  return MakeSynth(name, o, data_dir).bundle;
}

namespace {

/// Rings of the fine grid a measured HDR map is integrated over for rendering.
constexpr int kFineRings = 91;

/// Reference images of `views` under the true lighting: sphere lights and sky by
/// RenderSphereLights; a measured map has no analytic sampler here, so it is integrated
/// over a fine grid (91 rings, ~2 degree cells, 20x finer than the estimator's default)
/// and rendered by the path tracer with importance sampling by cell power (that grid's
/// radiance goes to `fine_radiance`).
std::vector<ImageRGB> RenderReference(const RayTracer& scene, const Mesh& mesh, const Vector3d& up,
                                      const std::vector<View>& views, const SynthLighting& lighting,
                                      const SynthOptions& o, std::vector<double>* fine_radiance) {
  if (lighting.equirect.pixels() == 0) return RenderSphereLights(mesh, views, lighting, o);
  const EnvMap fine(kFineRings, up);
  *fine_radiance = fine.FromEquirect(lighting.equirect, 64);
  TracerOptions to;
  to.spp = o.spp;
  to.bounces = o.bounces;
  to.seed = o.seed;
  to.min_throughput = 0;
  const CellSampler sampler(fine, *fine_radiance, {}, 0.05);
  return RenderEnvironment(scene, fine, views, *fine_radiance, sampler, to, true);
}

/// The lights of the room scenes (one-light ... lamp-and-sky, env-*), around the lighting's
/// centre; `sky_up` receives the sky's irradiance on a surface facing up (0: no sky).
void RoomLights(const std::string& name, const fs::path& data_dir, const Vector3d& up, SynthLighting* out,
                double* sky_up) {
  std::vector<SphereLight>& lights = out->lights;
  SynthLighting& lighting = *out;
  const Vector3d& center = lighting.center;
  *sky_up = 0;
  const bool lamps = name == "lamp-0.5m" || name == "lamp-1m" || name == "lamp-2m" || name == "lamp-4m" ||
                     name == "two-lamps" || name == "lamp-and-sky";
  if (name == "one-light") {
    // Far (200 m, 20 m radius: 5.7 degrees): the light's distance varies by < 1.5 % over
    // the room, so the environment-map model holds; near-light stresses it instead.
    lights.push_back(LightAt(center, Direction(30, 50), 200, 20.0, {1.0, 0.95, 0.85}, 3.0));
  } else if (name == "two-light") {
    lights.push_back(LightAt(center, Direction(15, 45), 200, 20.0, {1.0, 0.85, 0.65}, 2.5));
    lights.push_back(LightAt(center, Direction(80, 30), 200, 20.0, {0.55, 0.7, 1.0}, 1.2));
  } else if (name == "near-light") {
    lights.push_back(LightAt(center, Direction(40, 55), 0.6, 0.05, {1.0, 0.95, 0.85}, 1.0));
    lighting.far = false;
  } else if (lamps) {
    // Lamps in the room (issue 20): 5 cm spheres, irradiance 1 at the centre each.
    const double distance = name == "lamp-0.5m" ? 0.5 : name == "lamp-1m" ? 1.0 : name == "lamp-2m" ? 2.0
                            : name == "lamp-4m"  ? 4.0 : name == "two-lamps" ? 1.7 : 1.5;
    if (name == "two-lamps") {
      lights.push_back(LightAt(center, Direction(35, 50), 1.7, 0.05, {1.0, 0.8, 0.55}, 1.0));
      lights.push_back(LightAt(center, Direction(75, 35), 1.6, 0.05, {0.55, 0.75, 1.0}, 0.7));
    } else {
      lights.push_back(LightAt(center, Direction(40, 55), distance, 0.05, {1.0, 0.95, 0.85}, 1.0));
    }
    if (name == "lamp-and-sky") lighting.sky = Sky(up, *sky_up = 1.0 / 20);
    lighting.far = false;
  } else if (name == "sun-and-sky") {
    // The sun: 0.53 degrees across, 10 km away (parallel over the room); irradiance 3
    // facing it, the sky 1000x less on a surface facing up.
    lights.push_back(LightAt(center, Direction(35, 40), 1e4, 1e4 * std::tan(0.265 * kPi / 180), {1.0, 0.97, 0.9},
                             3.0));
    lighting.sky = Sky(up, *sky_up = 3.0 / 1000);
  } else {
    const fs::path hdr = data_dir / "hdri" / (name == "env-studio" ? "studio_small_03_1k.hdr" : "venice_sunset_1k.hdr");
    lighting.equirect = ReadHdr(hdr);
  }
}

/// The real reconstructed fragment (frag_115.ply) lit by a far sun-like sphere, seen by one
/// camera (two with a held-out view).
void Fragment115(const SynthOptions& o, const fs::path& data_dir, SceneBundle* b, SynthLighting* lighting,
                 std::vector<Camera>* cams) {
  const fs::path ply = data_dir / "mesh" / "frag_115.ply";
  b->mesh = ReadPly(ply);
  SanitizeMesh(&b->mesh, ply.string());
  // The fragment is in its first camera's frame (OpenCV: y down), so up is -y.
  b->up = -Vector3d::UnitY();
  Eigen::Vector3f lo, hi;
  MeshBounds(b->mesh, &lo, &hi);
  Vector3d& center = lighting->center;
  center = (0.5f * (lo + hi)).cast<double>();
  const double extent = (hi - lo).cast<double>().norm();
  cams->push_back(Camera::LookAt(Vector3d(center.x(), center.y() - 0.15 * extent, lo.z() - 0.35 * extent), center,
                                 b->up, o.width, o.height, 60));
  if (o.held_out_views > 0)
    cams->push_back(Camera::LookAt(Vector3d(center.x() + 0.3 * extent, center.y() - 0.2 * extent, lo.z() - 0.3 * extent),
                                   center, b->up, o.width, o.height, 60));
  const Vector3d dir = (-Vector3d::UnitY() * 1.2 + Vector3d(0.4, 0, -0.6)).normalized();
  // 50 extents away (0.7 degrees across): far, so the environment-map model holds.
  lighting->lights.push_back(LightAt(center, dir, 50 * extent, 0.6 * extent, {1.0, 0.95, 0.85}, 3.0));
}

/// The view's mask: pixels whose centre ray hits the geometry (as a reconstruction would give).
void MaskGeometry(const RayTracer& scene, View* view) {
  const Camera& cam = view->camera;
  view->valid.assign(view->image.pixels(), 0);
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      SurfacePoint hit;
      view->valid[static_cast<std::size_t>(y) * cam.width + x] =
          scene.Intersect(cam.center(), cam.RayDirection(x, y), &hit) ? 1 : 0;
    }
}

}  // namespace

SynthScene MakeSynth(const std::string& name, const SynthOptions& o, const fs::path& data_dir) {
  if (o.width < 8 || o.height < 8 || o.width > 4096 || o.height > 4096) throw InputError("synth: bad image size");
  if (o.held_out_views < 0 || o.held_out_views > 1) throw InputError("synth: held-out views must be 0 or 1");
  SynthScene scene_out;
  SceneBundle& b = scene_out.bundle;
  SynthLighting& lighting = scene_out.lighting;
  std::vector<SphereLight>& lights = lighting.lights;
  Vector3d& center = lighting.center;
  std::vector<Camera> cams;
  double sky_up = 0;  // the sky's irradiance on a surface facing up (truth.json)
  const bool lamps = name == "lamp-0.5m" || name == "lamp-1m" || name == "lamp-2m" || name == "lamp-4m" ||
                     name == "two-lamps" || name == "lamp-and-sky";
  const bool room = name == "one-light" || name == "two-light" || name == "near-light" || name == "sun-and-sky" ||
                    name == "env-studio" || name == "env-sunset" || lamps;
  if (room) {
    b.mesh = RoomCorner();
    b.up = Vector3d::UnitZ();
    center = Vector3d(1.1, 1.1, 0.5);
    cams = RoomCameras(o, b.up);
    RoomLights(name, data_dir, b.up, &lighting, &sky_up);
  } else if (name == "frag115") {
    Fragment115(o, data_dir, &b, &lighting, &cams);
  } else {
    std::string names;
    for (const auto& [n, d] : SynthSceneList()) names += (names.empty() ? "" : ", ") + n;
    throw InputError("unknown synthetic scene '" + name + "' (available: " + names + ")");
  }
  SanitizeMesh(&b.mesh, name);
  for (const Camera& cam : cams) {
    View view;
    view.camera = cam;
    b.views.push_back(view);
  }
  RayTracer scene(b.mesh);
  std::vector<ImageRGB> images;
  nlohmann::json t;
  t["scene"] = name;
  t["scene_center"] = {center.x(), center.y(), center.z()};
  t["lights"] = nlohmann::json::array();
  std::vector<double> fine_radiance;
  images = RenderReference(scene, b.mesh, b.up, b.views, lighting, o, &fine_radiance);
  if (lighting.equirect.pixels() > 0) {
    const EnvMap fine(kFineRings, b.up);
    const std::vector<double>& L = fine_radiance;
    for (const Vector3d& d : DominantDirections(fine, L, 2)) {
      double power = 0;
      for (int j = 0; j < fine.size(); ++j)
        if (AngleDeg(fine.direction(j), d) < 15)
          power += Luminance(L[3 * j], L[3 * j + 1], L[3 * j + 2]) * fine.solid_angle(j);
      t["lights"].push_back({{"type", "environment"}, {"direction", {d.x(), d.y(), d.z()}}, {"weight", power}});
    }
    t["environment_map"] = name == "env-studio" ? "studio_small_03_1k.hdr" : "venice_sunset_1k.hdr";
  }
  for (std::size_t v = 0; v < b.views.size(); ++v) {
    b.views[v].image = std::move(images[v]);
    MaskGeometry(scene, &b.views[v]);
  }
  for (const SphereLight& l : lights) {
    const Vector3d d = (l.position - center).normalized();
    t["lights"].push_back({{"type", name == "sun-and-sky" ? "sun" : "sphere"},
                           {"position", {l.position.x(), l.position.y(), l.position.z()}},
                           {"radius", l.radius},
                           {"rgb_power", {l.rgb_power.x(), l.rgb_power.y(), l.rgb_power.z()}},
                           {"distance", (l.position - center).norm()},
                           {"direction", {d.x(), d.y(), d.z()}}});
  }
  if (lighting.sky) t["sky"] = {{"irradiance_up", sky_up}, {"model", "(1 + 2 cos theta) / 3 above the horizon"}};
  if (o.held_out_views > 0) t["held_out_views"] = o.held_out_views;
  b.truth_json = t.dump(2) + "\n";
  return scene_out;
}

namespace {

/// Along a camera ray, where it enters the nearest of `lights` (infinity where it misses them).
double NearestSphere(const std::vector<SphereLight>& lights, const Vector3d& origin, const Vector3d& dir, int* which) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < lights.size(); ++i) {
    const Vector3d to = lights[i].position - origin;
    const double b = dir.dot(to), c = to.squaredNorm() - lights[i].radius * lights[i].radius, disc = b * b - c;
    if (disc < 0) continue;
    const double t = b - std::sqrt(disc);
    if (t > 0 && t < best) best = t, *which = static_cast<int>(i);
  }
  return best;
}

/// The lamps' spheres in `frame` where they are nearer than the surface: their radiance in
/// colour (a pixel's centre decides) and no depth.
void ShowLamps(const std::vector<SphereLight>& lights, const Camera& cam, SynthFrame* frame) {
  const Vector3d axis = cam.world_from_camera.block<3, 1>(0, 2);
  ParallelFor(0, frame->depth.size(), [&](std::size_t p) {
    const int x = static_cast<int>(p % cam.width), y = static_cast<int>(p / cam.width);
    const Vector3d dir = cam.RayDirection(x, y);
    int which = -1;
    const double t = NearestSphere(lights, cam.center(), dir, &which);
    const double surface = frame->depth[p] > 0 ? frame->depth[p] / dir.dot(axis) : std::numeric_limits<double>::infinity();
    if (which < 0 || t >= surface) return;
    const Vector3d radiance = lights[which].Radiance();
    for (int c = 0; c < 3; ++c) frame->color.at(x, y)[c] = static_cast<float>(radiance[c]);
    frame->depth[p] = 0;
  });
}

}  // namespace

std::vector<SynthFrame> RenderSynthFrames(const std::string& name, const SynthOptions& o, const fs::path& data_dir,
                                          int frames, std::string* truth_json) {
  if (frames < 1 || frames > 10000) throw InputError("synthetic frames: the frame count must be between 1 and 10000");
  SynthOptions first = o;
  first.spp = 1;  // only the geometry, the lighting and the first camera are needed here
  first.held_out_views = 0;
  const SynthScene scene = MakeSynth(name, first, data_dir);
  if (truth_json) *truth_json = scene.bundle.truth_json.value_or("");
  const Camera& c0 = scene.bundle.views[0].camera;
  const Vector3d up = scene.bundle.up.normalized(), centre = scene.lighting.center;
  std::vector<SynthFrame> out(frames);
  std::vector<View> views(frames);
  for (int k = 0; k < frames; ++k) {
    const double angle = frames == 1 ? 0.0 : (-20.0 + 40.0 * k / (frames - 1)) * kPi / 180;
    const Eigen::Matrix3d R = Eigen::AngleAxisd(angle, up).toRotationMatrix();
    Camera cam = c0;
    cam.world_from_camera.block<3, 3>(0, 0) = R * c0.world_from_camera.block<3, 3>(0, 0);
    cam.world_from_camera.block<3, 1>(0, 3) = centre + R * (c0.center() - centre);
    views[k].camera = cam;
    out[k].camera = cam;
  }
  RayTracer tracer(scene.bundle.mesh);
  std::vector<double> fine_radiance;
  std::vector<ImageRGB> colour = RenderReference(tracer, scene.bundle.mesh, up, views, scene.lighting, o, &fine_radiance);
  for (int k = 0; k < frames; ++k) {
    const Camera& cam = out[k].camera;
    out[k].color = std::move(colour[k]);
    out[k].depth.assign(static_cast<std::size_t>(cam.width) * cam.height, 0.f);
    const Vector3d axis = cam.world_from_camera.block<3, 1>(0, 2);
    std::vector<float>& depth = out[k].depth;
    ParallelFor(0, depth.size(), [&](std::size_t p) {
      const int x = static_cast<int>(p % cam.width), y = static_cast<int>(p / cam.width);
      SurfacePoint hit;
      const Vector3d dir = cam.RayDirection(x, y);
      if (!tracer.Intersect(cam.center(), dir, &hit)) return;
      const double z = (hit.position - cam.center()).dot(axis);
      depth[p] = static_cast<float>(z);
      if (!o.depth_noise) return;
      Rng rng(o.seed, 0x5e45, static_cast<std::uint64_t>(k), p);
      if (std::abs(hit.geometric.dot(dir)) < 0.2 || rng.Uniform() < 0.005) {
        depth[p] = 0;
        return;
      }
      const double sigma = 0.0012 + 0.0019 * (z - 0.4) * (z - 0.4);
      const double u1 = std::max(rng.Uniform(), 1e-12), u2 = rng.Uniform();
      depth[p] = static_cast<float>(z + sigma * std::sqrt(-2 * std::log(u1)) * std::cos(2 * kPi * u2));
    });
    if (o.lamps_seen) ShowLamps(scene.lighting.lights, cam, &out[k]);
    if (o.depth_noise) {  // structured light loses depth along jumps (shadowed / mixed pixels)
      const std::vector<float> d0 = depth;
      for (int y = 1; y + 1 < cam.height; ++y)
        for (int x = 1; x + 1 < cam.width; ++x) {
          const std::size_t p = static_cast<std::size_t>(y) * cam.width + x;
          const float z = d0[p];
          bool edge = false;
          for (const std::size_t q : {p - 1, p + 1, p - cam.width, p + cam.width})
            edge = edge || (z > 0 && d0[q] > 0 && std::abs(d0[q] - z) > 0.03f * z) || (z > 0 && d0[q] == 0);
          if (edge && Rng(o.seed, 0xed9e, static_cast<std::uint64_t>(k), p).Uniform() < 0.5) depth[p] = 0;
        }
    }
  }
  return out;
}

}  // namespace lp
