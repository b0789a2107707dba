#include "ui/viewer.h"

#include <unistd.h>

#include <imgui.h>
#include <imgui_impl_glfw.h>
#include <imgui_impl_opengl3.h>

#include <algorithm>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <thread>
#include <fstream>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "common/color.h"
#include "common/error.h"
#include "common/image_io.h"
#include "estimation/error_display.h"
#include "ui/mesh_display.h"
#include "ui/viewer_internal.h"

namespace lp::ui {

namespace {

constexpr float kPanelWidth = 380;
constexpr float kEnvHeight = 250;
/// While the view moves, meshes larger than this are drawn from a coarse copy (Mesa
/// rasterizes on the CPU; docs/benchmarks.md), at half resolution.
constexpr int kMovingTriangles = 20000;

std::string g_glfw_error;

void OnGlfwError(int code, const char* description) {
  g_glfw_error = std::to_string(code) + ": " + (description ? description : "");
}

/// Blue (0) -> green -> yellow -> red (1): the depth and environment-map colour scale
/// (errors use Viridis, as the exported error_view*.png do).
Eigen::Vector3f Heat(float t) {
  t = std::clamp(t, 0.f, 1.f);
  const float r = std::clamp(1.5f - std::abs(4 * t - 3), 0.f, 1.f);
  const float g = std::clamp(1.5f - std::abs(4 * t - 2), 0.f, 1.f);
  const float b = std::clamp(1.5f - std::abs(4 * t - 1), 0.f, 1.f);
  return {r, g, b};
}

ImageRgb8 DepthDisplay(const DepthImage& depth) {
  ImageRgb8 out;
  out.width = depth.width;
  out.height = depth.height;
  out.data.assign(depth.pixels() * 3, 0);
  for (std::size_t i = 0; i < depth.pixels(); ++i) {
    const std::uint16_t mm = depth.data[i];
    if (mm == 0) continue;
    const Eigen::Vector3f c = Heat(std::clamp((mm - 300.f) / 4700.f, 0.f, 1.f));
    for (int k = 0; k < 3; ++k) out.data[3 * i + k] = static_cast<std::uint8_t>(255 * c[k]);
  }
  return out;
}

/// The estimate's environment map as a display image (exposure from its 99th percentile).
ImageRgb8 EnvDisplay(const EnvMap& env, const std::vector<double>& lambda, int height) {
  const ImageRGB eq = env.ToEquirect(lambda, height);
  std::vector<float> lum;
  for (std::size_t i = 0; i < eq.data.size(); i += 3)
    lum.push_back(static_cast<float>(Luminance(eq.data[i], eq.data[i + 1], eq.data[i + 2])));
  std::sort(lum.begin(), lum.end());
  const float top = lum.empty() ? 1.f : lum[std::min(lum.size() - 1, lum.size() * 99 / 100)];
  return EncodeSrgb8(eq, top > 0 ? 0.9f / top : 1.f);
}

Eigen::Matrix4f LookAtMatrix(const Eigen::Vector3f& eye, const Eigen::Vector3f& target, const Eigen::Vector3f& up) {
  const Eigen::Vector3f f = (target - eye).normalized();
  Eigen::Vector3f s = f.cross(up);
  if (s.norm() < 1e-6f) s = f.cross(Eigen::Vector3f::UnitX());
  s.normalize();
  const Eigen::Vector3f u = s.cross(f);
  Eigen::Matrix4f m = Eigen::Matrix4f::Identity();
  m.row(0) << s.transpose(), -s.dot(eye);
  m.row(1) << u.transpose(), -u.dot(eye);
  m.row(2) << -f.transpose(), f.dot(eye);
  return m;
}

}  // namespace

const char* ToString(Shading s) {
  switch (s) {
    case Shading::kAlbedo: return "albedo";
    case Shading::kLit: return "lit";
    case Shading::kError: return "error";
    case Shading::kNormals: return "normals";
  }
  return "?";
}

void OrbitCamera::Horizontal(Eigen::Vector3f* a, Eigen::Vector3f* b) const {
  *a = up.cross(Eigen::Vector3f::UnitX());
  if (a->norm() < 1e-3f) *a = up.cross(Eigen::Vector3f::UnitY());
  a->normalize();
  *b = up.cross(*a);
}

Eigen::Vector3f OrbitCamera::Eye() const {
  // Azimuth around `up`, elevation from the horizontal plane.
  Eigen::Vector3f a, b;
  Horizontal(&a, &b);
  const Eigen::Vector3f dir = std::cos(pitch) * (std::cos(yaw) * a + std::sin(yaw) * b) + std::sin(pitch) * up;
  return target + distance * dir;
}

Eigen::Matrix4f OrbitCamera::View() const { return LookAtMatrix(Eye(), target, up); }

Eigen::Matrix4f OrbitCamera::Projection(float aspect) const {
  const float fovy = 50.f * 3.14159265f / 180.f, n = std::max(0.01f, distance * 0.01f), f = distance * 20.f;
  const float t = 1.f / std::tan(fovy / 2);
  Eigen::Matrix4f p = Eigen::Matrix4f::Zero();
  p(0, 0) = t / aspect;
  p(1, 1) = t;
  p(2, 2) = (f + n) / (n - f);
  p(2, 3) = 2 * f * n / (n - f);
  p(3, 2) = -1;
  return p;
}

Viewer::Viewer(const ViewerOptions& options, GLFWwindow* window)
    : options_(options),
      window_(window),
      session_(options.session),
      settings_(options.estimate),
      mesh_program_(MeshProgram()),
      line_program_(LineProgram()) {
  if (!options.script.empty()) script_ = std::make_unique<ScriptRunner>(options.script, this);
  session_.SetLive(options.session.live, settings_);
  session_.Open(options.input.empty() ? "auto" : options.input);
}

Viewer::~Viewer() = default;

void Viewer::ResetCamera() {
  if (!shown_mesh_ || shown_mesh_->positions.empty()) return;
  Eigen::Vector3f lo, hi;
  MeshBounds(*shown_mesh_, &lo, &hi);
  camera_.target = 0.5f * (lo + hi);
  camera_.distance = std::max(0.2f, 1.2f * (hi - lo).norm());
  camera_.yaw = 0.6f;
  camera_.pitch = 0.45f;
  if (est_.scene) camera_.up = est_.scene->up.cast<float>();
  camera_set_ = true;
  // Look from where the scene was captured (the first keyframe, else the live camera),
  // a little higher: a room is seen from inside, not from behind its walls.
  Eigen::Vector3f eye;
  if (est_.scene && !est_.scene->views.empty()) eye = est_.scene->views[0].camera.center().cast<float>();
  else if (live_.has_pose) eye = live_.camera_pose.block<3, 1>(0, 3).cast<float>();
  else return;
  Eigen::Vector3f d = eye - camera_.target;
  if (d.norm() < 1e-3f) return;
  d.normalize();
  Eigen::Vector3f a, b;
  camera_.Horizontal(&a, &b);
  camera_.yaw = std::atan2(d.dot(b), d.dot(a));
  camera_.pitch = std::clamp(std::asin(std::clamp(d.dot(camera_.up), -1.f, 1.f)) + 0.25f, -1.2f, 1.2f);
  camera_.distance = std::max(0.2f, 0.9f * (hi - lo).norm());
}

/// The mesh shown: the estimate's snapshot once there is one, else the live model.
void Viewer::SyncModel() {
  const bool want_snapshot = est_.scene != nullptr;
  std::shared_ptr<const Mesh> mesh = want_snapshot ? SnapshotMesh() : live_.model;
  if (mesh == shown_mesh_ && want_snapshot == showing_snapshot_) return;
  if (!want_snapshot && live_.model_version == model_version_ && !showing_snapshot_) return;
  model_version_ = live_.model_version;
  showing_snapshot_ = want_snapshot;
  shown_mesh_ = mesh;
  has_coarse_ = false;
  if (mesh) {
    mesh_.SetGeometry(*mesh);
    // A coarse copy to draw while the view moves (not for a model still growing: it is
    // re-meshed twice a second).
    if ((want_snapshot || !live_.reconstructing) && static_cast<int>(mesh->triangles.size()) > kMovingTriangles) {
      const Mesh coarse = SimplifyForDisplay(*mesh, kMovingTriangles, &cluster_of_);
      coarse_mesh_.SetGeometry(coarse);
      has_coarse_ = true;
    }
    if (!camera_set_ || (want_snapshot && camera_.up != est_.scene->up.cast<float>())) ResetCamera();
  } else {
    mesh_.SetGeometry(Mesh{});
  }
  lit_version_ = ~0ull;  // recolour
  shaded_ = Shading::kNormals;
}

std::shared_ptr<const Mesh> Viewer::SnapshotMesh() {
  if (!est_.result || est_.result->openings.empty()) {
    opened_for_.reset();
    opened_mesh_.reset();
    return std::shared_ptr<const Mesh>(est_.scene, &est_.scene->mesh);
  }
  if (opened_for_ != est_.result) {
    opened_for_ = est_.result;
    opened_mesh_ = std::make_shared<const Mesh>(WithoutShapes(est_.scene->mesh, est_.result->openings));
  }
  return opened_mesh_;
}

void Viewer::SyncShading() {
  if (!shown_mesh_) return;
  const bool lit_ready = showing_snapshot_ && est_.lit && est_.lit->size() == shown_mesh_->positions.size();
  // The albedo the estimate was made under, when it refined the reconstruction's (de-lit).
  const std::vector<Eigen::Vector3f>* refined =
      showing_snapshot_ && est_.result && est_.result->albedo.size() == shown_mesh_->positions.size()
          ? &est_.result->albedo
          : nullptr;
  if (shading_ == shaded_ && shading_ == Shading::kNormals) return;
  if (shading_ == shaded_ && shading_ == Shading::kAlbedo && shown_refined_albedo_ == (refined != nullptr)) return;
  if ((shading_ == Shading::kLit || shading_ == Shading::kError) && shading_ == shaded_ &&
      est_.lit_version == lit_version_)
    return;
  std::vector<Eigen::Vector3f> colors;
  if (shading_ == Shading::kLit && lit_ready) {
    colors = *est_.lit;
  } else if (shading_ == Shading::kError && lit_ready && est_.error) {
    colors.resize(est_.error->size());
    for (std::size_t i = 0; i < colors.size(); ++i) {
      const float e = (*est_.error)[i];
      // Error heat (0 .. kErrorDisplayFraction of the white level, as error_view*.png) in
      // display values; unseen vertices grey.
      Eigen::Vector3f h;
      Viridis(e / kErrorDisplayFraction, h.data());
      colors[i] = std::isnan(e) ? Eigen::Vector3f::Constant(0.05f) : Eigen::Vector3f(h.array().pow(2.2f));
    }
  } else {
    colors = shading_ == Shading::kAlbedo && refined ? *refined : shown_mesh_->albedo;
  }
  shown_refined_albedo_ = shading_ == Shading::kAlbedo && refined;
  colors.resize(shown_mesh_->positions.size(), Eigen::Vector3f::Constant(0.5f));
  mesh_.SetColors(colors);
  if (has_coarse_)
    coarse_mesh_.SetColors(AverageOverClusters(colors, cluster_of_, static_cast<int>(coarse_mesh_.vertices())));
  shaded_ = shading_;
  lit_version_ = est_.lit_version;
}

std::string Viewer::SceneKey(const Rect& r) const {
  char key[512];
  const Eigen::Vector3f& t = camera_.target;
  const bool live_camera = live_.has_pose && !showing_snapshot_;
  std::snprintf(key, sizeof key, "%g %g %g %g %g %g %g %g %g | %g %g | %d %d %g %d %d | %llu %llu %d %p %llu %llu %d",
                t.x(), t.y(), t.z(), camera_.yaw, camera_.pitch, camera_.distance, camera_.up.x(), camera_.up.y(),
                camera_.up.z(), r.w, r.h, static_cast<int>(shading_), static_cast<int>(shaded_), exposure_,
                headlight_ ? 1 : 0, selected_keyframe_, static_cast<unsigned long long>(lit_version_),
                static_cast<unsigned long long>(model_version_), showing_snapshot_ ? 1 : 0,
                static_cast<const void*>(shown_mesh_.get()), static_cast<unsigned long long>(est_.version),
                static_cast<unsigned long long>(live_camera ? live_.frame_version : 0), moving_ ? 1 : 0);
  return key;
}

void Viewer::DrawScene(const Rect& r) {
  int fb_w, fb_h;
  glfwGetFramebufferSize(window_, &fb_w, &fb_h);
  int win_w, win_h;
  glfwGetWindowSize(window_, &win_w, &win_h);
  const float sx = static_cast<float>(fb_w) / std::max(1, win_w), sy = static_cast<float>(fb_h) / std::max(1, win_h);
  // While the view moves: half the pixels' side (a quarter of the fill), sharp again at rest.
  const float scale = moving_ ? 0.5f : 1.f;
  target_.Bind(std::max(1, static_cast<int>(r.w * sx * scale)), std::max(1, static_cast<int>(r.h * sy * scale)));
  glClearColor(0.13f, 0.14f, 0.16f, 1.f);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glEnable(GL_DEPTH_TEST);
  const Eigen::Matrix4f vp = camera_.Projection(r.w / std::max(1.f, r.h)) * camera_.View();

  mesh_program_.Use();
  glUniformMatrix4fv(mesh_program_.Uniform("view_projection"), 1, GL_FALSE, vp.data());
  glUniform1i(mesh_program_.Uniform("mode"), shading_ == Shading::kNormals ? 1 : 0);
  const bool lit = shading_ == Shading::kLit && shaded_ == Shading::kLit;
  glUniform1i(mesh_program_.Uniform("headlight"), headlight_ && shading_ == Shading::kAlbedo ? 1 : 0);
  glUniform1f(mesh_program_.Uniform("exposure"), lit ? exposure_ : 1.f);
  const Eigen::Vector3f eye = camera_.Eye();
  glUniform3f(mesh_program_.Uniform("eye"), eye.x(), eye.y(), eye.z());
  (moving_ && has_coarse_ ? coarse_mesh_ : mesh_).Draw();

  // Keyframe frusta, the live camera, the dominant light directions.
  lines_.Clear();
  const float size = std::max(0.05f, camera_.distance * 0.06f);
  auto frustum = [&](const Camera& cam, const Eigen::Vector3f& color) {
    const Eigen::Vector3f c = cam.center().cast<float>();
    const double us[4] = {0, double(cam.width - 1), double(cam.width - 1), 0};
    const double vs[4] = {0, 0, double(cam.height - 1), double(cam.height - 1)};
    Eigen::Vector3f corner[4];
    const Eigen::Vector3d forward = cam.world_from_camera.block<3, 1>(0, 2);
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector3d d = cam.RayDirection(us[k], vs[k]);
      corner[k] = c + (d / d.dot(forward)).cast<float>() * size;
    }
    for (int k = 0; k < 4; ++k) {
      lines_.Add(c, corner[k], color);
      lines_.Add(corner[k], corner[(k + 1) % 4], color);
    }
  };
  if (est_.scene)
    for (std::size_t k = 0; k < est_.scene->views.size(); ++k)
      frustum(est_.scene->views[k].camera, static_cast<int>(k) == selected_keyframe_ ? Eigen::Vector3f(1, 0.55f, 0)
                                                                                    : Eigen::Vector3f(0.3f, 0.8f, 1));
  if (live_.has_pose && live_.frame && !showing_snapshot_) {
    Camera cam = live_.frame->depth_intrinsics;
    cam.world_from_camera = live_.camera_pose;
    if (cam.fx > 0) frustum(cam, Eigen::Vector3f(0.3f, 1, 0.3f));
  }
  if (!est_.dominant.empty()) {
    const float reach = camera_.distance * 0.6f;
    for (std::size_t k = 0; k < est_.dominant.size(); ++k) {
      const Eigen::Vector3f d = est_.dominant[k].cast<float>();
      const Eigen::Vector3f color = k == 0 ? Eigen::Vector3f(1, 0.9f, 0.1f) : Eigen::Vector3f(1, 0.6f, 0.2f);
      lines_.Add(camera_.target, camera_.target + reach * d, color);
      // A small star at the end.
      const Eigen::Vector3f tip = camera_.target + reach * d;
      const float s = size * 0.5f;
      for (int a = 0; a < 3; ++a)
        lines_.Add(tip - s * Eigen::Vector3f::Unit(a), tip + s * Eigen::Vector3f::Unit(a), color);
    }
  }
  line_program_.Use();
  glUniformMatrix4fv(line_program_.Uniform("view_projection"), 1, GL_FALSE, vp.data());
  lines_.Draw();
  // The lamps over everything: they are often behind a wall or outside the scan.
  glDisable(GL_DEPTH_TEST);
  lines_.Clear();
  AddLightMarkers(size);
  lines_.Draw();
  view_projection_ = vp;
  RenderTarget::Unbind();
  glViewport(0, 0, fb_w, fb_h);
  ++scene_renders_;
}

namespace {

/// A light's colour as its marker draws it: its brightest channel at full scale, none below
/// 0.15 (white for a dark light).
Eigen::Vector3f MarkerColour(const Eigen::Vector3d& rgb) {
  const double peak = rgb.maxCoeff();
  const Eigen::Vector3f colour = peak > 0 ? Eigen::Vector3f((rgb / peak).cast<float>()) : Eigen::Vector3f::Ones();
  return colour.cwiseMax(0.15f);
}

}  // namespace

/// Every light's marker, each opening's outline and the lights' 95 % regions.
void Viewer::AddLightMarkers(float size) {
  AddLampMarkers(size);
  AddEmitterOutlines();
  AddOpeningOutlines();
  AddSunMarkers(size);
  AddRegions();
}

/// Each point light as a small octahedron with its axes, in its colour (brightest channel
/// at full scale), sized by the square root of its share of the brightest lamp.
void Viewer::AddLampMarkers(float size) {
  const std::vector<PointLight> lamps = est_.lighting.Of<PointLight>();
  double top = 0;
  for (const PointLight& l : lamps) top = std::max(top, Luminance(l.intensity.x(), l.intensity.y(), l.intensity.z()));
  if (!(top > 0)) return;
  for (const PointLight& l : lamps) {
    const Eigen::Vector3f p = l.position.cast<float>();
    const double lum = Luminance(l.intensity.x(), l.intensity.y(), l.intensity.z());
    const float s = size * (0.4f + 0.6f * static_cast<float>(std::sqrt(std::max(0.0, lum / top))));
    const Eigen::Vector3f color = MarkerColour(l.intensity);
    Eigen::Vector3f tip[6];
    for (int a = 0; a < 3; ++a) {
      tip[2 * a] = p + s * Eigen::Vector3f::Unit(a);
      tip[2 * a + 1] = p - s * Eigen::Vector3f::Unit(a);
      lines_.Add(tip[2 * a], tip[2 * a + 1], color);
    }
    for (int a = 0; a < 3; ++a)
      for (int b = a + 1; b < 3; ++b)
        for (int i = 0; i < 2; ++i)
          for (int j = 0; j < 2; ++j) lines_.Add(tip[2 * a + i], tip[2 * b + j], color);
  }
}

/// Each glowing surface's outline, in its colour (brightest channel at full scale), a
/// centimetre off the surface on the side that glows; a pane over a hole (on no surface the
/// lit shading could show glowing) hatched too, seven lines across each triangle.
void Viewer::AddEmitterOutlines() {
  for (const EmitterLight& e : est_.lighting.Of<EmitterLight>()) {
    if (!e.shape) continue;
    const Eigen::Vector3f color = MarkerColour(e.radiance);
    for (const OutlineEdge& edge : OutlineOf(e.shape))
      lines_.Add(edge.from + 0.01f * edge.normal, edge.to + 0.01f * edge.normal, color);
    if (!e.in_a_hole) continue;
    const EmitterShape& s = *e.shape;
    for (std::size_t t = 0; t < s.a.size(); ++t)
      for (int k = 1; k < 8; ++k) {
        const Eigen::Vector3f lift = 0.01f * s.normal[t];
        lines_.Add(s.a[t] + (s.b[t] - s.a[t]) * (k / 8.f) + lift, s.a[t] + (s.c[t] - s.a[t]) * (k / 8.f) + lift, color);
      }
  }
}

void Viewer::AddOpeningOutlines() {
  if (!est_.result) return;
  const Eigen::Vector3f sky(0.45f, 0.75f, 1.f);
  for (const auto& shape : est_.result->openings) {
    if (!shape) continue;
    for (const OutlineEdge& edge : OutlineOf(shape))
      for (const float side : {0.01f, -0.01f}) lines_.Add(edge.from + side * edge.normal, edge.to + side * edge.normal, sky);
  }
}

const std::vector<OutlineEdge>& Viewer::OutlineOf(const std::shared_ptr<const EmitterShape>& shape) const {
  if (outlines_.size() > 16) outlines_.clear();  // (the shapes of estimates gone)
  auto [it, added] = outlines_.try_emplace(shape);
  if (added) it->second = Outline(*shape);
  return it->second;
}

const LightUncertainty* Viewer::UncertaintyOf(std::size_t k) const {
  if (!est_.result || est_.result->uncertainty.size() != est_.lighting.lights.size() ||
      est_.result->lighting.lights.size() != est_.lighting.lights.size() || k >= est_.lighting.lights.size())
    return nullptr;
  if (!SameShape(est_.result->lighting.lights[k], est_.lighting.lights[k])) return nullptr;
  return &est_.result->uncertainty[k];
}

namespace {

/// The lights' colour as the markers draw it, dimmed.
Eigen::Vector3f Dimmed(const Eigen::Vector3d& rgb) { return 0.7f * MarkerColour(rgb); }

}  // namespace

void Viewer::AddRegions() {
  constexpr int kSegments = 32;
  const auto ellipse = [&](const Eigen::Vector3f& centre, const Eigen::Vector3f& u, const Eigen::Vector3f& v,
                           const Eigen::Vector3f& colour) {
    for (int k = 0; k < kSegments; ++k) {
      const float t0 = 6.2831853f * k / kSegments, t1 = 6.2831853f * (k + 1) / kSegments;
      lines_.Add(centre + std::cos(t0) * u + std::sin(t0) * v, centre + std::cos(t1) * u + std::sin(t1) * v, colour);
    }
  };
  for (std::size_t k = 0; k < est_.lighting.lights.size(); ++k) {
    const LightUncertainty* u = UncertaintyOf(k);
    Eigen::Vector3d semi;
    Eigen::Matrix3d axes;
    if (!u) continue;
    if (const PointLight* l = std::get_if<PointLight>(&est_.lighting.lights[k])) {
      if (!Region95(u->shape_covariance, 3, &semi, &axes)) continue;
      const Eigen::Vector3f p = l->position.cast<float>(), colour = Dimmed(l->intensity);
      Eigen::Vector3f a[3];
      for (int i = 0; i < 3; ++i) a[i] = (semi[i] * axes.col(i)).cast<float>();
      ellipse(p, a[0], a[1], colour);
      ellipse(p, a[0], a[2], colour);
      ellipse(p, a[1], a[2], colour);
    } else if (const DirectionalLight* d = std::get_if<DirectionalLight>(&est_.lighting.lights[k])) {
      if (!Region95(u->shape_covariance, 2, &semi, &axes)) continue;
      // The cone's two widest angles (the third axis is the direction itself), drawn around
      // the marker at the marker's distance.
      const Eigen::Vector3f centre = SunMarkerCentre(*d);
      const float reach = (centre - camera_.target).norm();
      const Eigen::Vector3f a = reach * std::tan(std::min(1.4, semi[2])) * axes.col(2).cast<float>();
      const Eigen::Vector3f b = reach * std::tan(std::min(1.4, semi[1])) * axes.col(1).cast<float>();
      ellipse(centre, a, b, Dimmed(d->irradiance));
    }
  }
}

/// Where a directional light's marker is drawn: out along its direction from the orbit
/// target, inside the view and short of the dominant light's star.
Eigen::Vector3f Viewer::SunMarkerCentre(const DirectionalLight& l) const {
  return camera_.target + camera_.distance * 0.45f * l.direction.normalized().cast<float>();
}

/// Each directional light as a sun far out along its direction (a ring facing the scene with
/// eight rays), in its colour, with a dashed line to the scene's centre.
void Viewer::AddSunMarkers(float size) {
  sun_marker_size_ = size;
  for (const DirectionalLight& l : est_.lighting.Of<DirectionalLight>()) {
    const Eigen::Vector3f d = l.direction.normalized().cast<float>(), centre = SunMarkerCentre(l);
    const double peak = l.irradiance.maxCoeff();
    Eigen::Vector3f color = peak > 0 ? Eigen::Vector3f((l.irradiance / peak).cast<float>()) : Eigen::Vector3f::Ones();
    color = color.cwiseMax(0.15f);
    const Eigen::Vector3f a = d.unitOrthogonal(), b = d.cross(a);
    const float r = size;
    constexpr int kSegments = 16;
    for (int k = 0; k < kSegments; ++k) {
      const float t0 = 6.2831853f * k / kSegments, t1 = 6.2831853f * (k + 1) / kSegments;
      lines_.Add(centre + r * (std::cos(t0) * a + std::sin(t0) * b), centre + r * (std::cos(t1) * a + std::sin(t1) * b),
                 color);
      if (k % 2 == 0)
        lines_.Add(centre + 1.3f * r * (std::cos(t0) * a + std::sin(t0) * b),
                   centre + 1.8f * r * (std::cos(t0) * a + std::sin(t0) * b), color);
    }
    for (int k = 0; k < 10; k += 2)
      lines_.Add(camera_.target + (k / 10.f) * (centre - camera_.target),
                 camera_.target + ((k + 1) / 10.f) * (centre - camera_.target), color);
  }
}

void Viewer::HandleMouse(const Rect& r) {
  ImGuiIO& io = ImGui::GetIO();
  const ImVec2 m = io.MousePos;
  const bool inside = r.Contains(m.x, m.y) && !io.WantCaptureMouse;
  if (inside && io.MouseWheel != 0) camera_.distance *= std::pow(0.88f, io.MouseWheel);
  for (int button = 0; button < 2; ++button) {
    if (inside && ImGui::IsMouseClicked(button)) {
      dragging_ = true;
      drag_moved_ = false;
      drag_x_ = m.x;
      drag_y_ = m.y;
    }
  }
  if (dragging_) {
    const float dx = io.MouseDelta.x, dy = io.MouseDelta.y;
    if (std::abs(m.x - drag_x_) + std::abs(m.y - drag_y_) > 3) drag_moved_ = true;
    if (ImGui::IsMouseDown(0)) {
      camera_.yaw -= dx * 0.008f;
      camera_.pitch = std::clamp(camera_.pitch + dy * 0.008f, -1.5f, 1.5f);
    } else if (ImGui::IsMouseDown(1)) {
      const Eigen::Matrix4f v = camera_.View();
      const Eigen::Vector3f right = v.block<1, 3>(0, 0).transpose(), up = v.block<1, 3>(1, 0).transpose();
      const float scale = camera_.distance * 0.0015f;
      camera_.target += (-dx * right + dy * up) * scale;
    }
    if (ImGui::IsMouseReleased(0) && !drag_moved_ && est_.scene) {
      // A click: the keyframe whose camera centre is nearest on screen (within 20 px).
      const Eigen::Matrix4f vp = camera_.Projection(r.w / std::max(1.f, r.h)) * camera_.View();
      float best = 20;
      int pick = -1;
      for (std::size_t k = 0; k < est_.scene->views.size(); ++k) {
        const Eigen::Vector4f p = vp * est_.scene->views[k].camera.center().cast<float>().homogeneous();
        if (p.w() <= 0) continue;
        const float x = r.x + (p.x() / p.w() * 0.5f + 0.5f) * r.w, y = r.y + (0.5f - p.y() / p.w() * 0.5f) * r.h;
        const float d = std::hypot(x - m.x, y - m.y);
        if (d < best) best = d, pick = static_cast<int>(k);
      }
      if (pick >= 0) selected_keyframe_ = pick;
    }
    if (!ImGui::IsMouseDown(0) && !ImGui::IsMouseDown(1)) dragging_ = false;
  }
}

void Viewer::PanelSource() {
  ImGui::SetNextWindowPos(ImVec2(0, 0));
  ImGui::SetNextWindowSize(ImVec2(kPanelWidth, 330));
  ImGui::Begin("Source", nullptr, ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse);
  ImGui::TextWrapped("%s", live_.open ? live_.source.c_str() : "nothing open");
  if (ImGui::Button("Demo")) session_.Open("demo");
  ImGui::SameLine();
  if (ImGui::Button("Camera")) session_.Open("camera");
  ImGui::SameLine();
  ImGui::SetNextItemWidth(170);
  ImGui::InputTextWithHint("##path", ".oni, directory or bundle", path_field_, sizeof path_field_);
  ImGui::SameLine();
  if (ImGui::Button("Open") && path_field_[0]) session_.Open(path_field_);
  if (live_.recording) {
    ImGui::TextColored(ImVec4(1, 0.35f, 0.3f, 1), "recording: %d frames, %.1f s", live_.recorded_frames,
                       live_.recorded_seconds);
    ImGui::SameLine();
    if (ImGui::Button("Stop recording")) session_.StopRecording();
  } else if (live_.is_camera && live_.open) {
    ImGui::SetNextItemWidth(170);
    ImGui::InputText("##record", record_field_, sizeof record_field_);
    ImGui::SameLine();
    ImGui::SetNextItemWidth(50);
    ImGui::InputFloat("s##seconds", &record_seconds_, 0, 0, "%.0f");
    ImGui::SameLine();
    if (ImGui::Button("Record") && record_field_[0] && record_seconds_ > 0)
      session_.Record(record_field_, record_seconds_);
  }
  if (!live_.recording && !live_.record_message.empty()) ImGui::TextWrapped("%s", live_.record_message.c_str());
  if (!live_.is_bundle && live_.open) {
    // While recording the camera keeps playing: the Recorder takes every frame it sends.
    ImGui::BeginDisabled(live_.recording);
    if (ImGui::Button(live_.playing ? "Pause" : "Play")) session_.SetPlaying(!live_.playing);
    ImGui::EndDisabled();
    if (live_.frame_count > 0) {
      ImGui::SameLine();
      ImGui::SetNextItemWidth(150);
      seek_frame_ = static_cast<float>(live_.position);
      if (ImGui::SliderFloat("##seek", &seek_frame_, 0, static_cast<float>(live_.frame_count - 1), "frame %.0f"))
        session_.Seek(static_cast<std::int64_t>(seek_frame_));
      ImGui::SameLine();
      ImGui::SetNextItemWidth(70);
      if (ImGui::SliderFloat("speed", &speed_, 0.f, 4.f, speed_ == 0 ? "max" : "%.1fx")) session_.SetSpeed(speed_);
    }
    ImGui::Text("%.1f frames/s in, %.1f reconstructed, %lld dropped", live_.source_fps, live_.processed_fps,
                static_cast<long long>(live_.dropped));
    const ImVec4 state_color = live_.tracking == TrackingState::kTracking ? ImVec4(0.4f, 1, 0.4f, 1)
                               : live_.tracking == TrackingState::kLost   ? ImVec4(1, 0.4f, 0.3f, 1)
                                                                          : ImVec4(0.8f, 0.8f, 0.8f, 1);
    ImGui::TextColored(state_color, "tracking: %s  (%lld tracked, %lld lost)%s%s", ToString(live_.tracking),
                       static_cast<long long>(live_.frames_tracked), static_cast<long long>(live_.frames_lost),
                       live_.tracking_reason.empty() ? "" : " - ", live_.tracking_reason.c_str());
    if (ImGui::Button(live_.reconstructing ? "Stop reconstruction" : "Start reconstruction")) {
      if (live_.reconstructing) session_.StopReconstruction();
      else session_.StartReconstruction();
    }
    ImGui::SameLine();
    if (ImGui::Button("Reset")) session_.ResetReconstruction();
    ImGui::SameLine();
    ImGui::Text("model: %zu tri", live_.model ? live_.model->triangles.size() : std::size_t{0});
  }
  if (live_.frame && live_.frame_version != frame_version_) {
    frame_version_ = live_.frame_version;
    color_tex_.Upload(live_.frame->color);
    depth_tex_.Upload(DepthDisplay(live_.frame->depth));
  }
  const ImVec2 at = ImGui::GetCursorScreenPos();
  live_rect_ = {at.x, at.y, 360, 135};
  if (color_tex_.width() > 0 && live_.frame) {
    ImGui::Image(reinterpret_cast<void*>(static_cast<std::intptr_t>(color_tex_.id())), ImVec2(178, 134));
    ImGui::SameLine();
    ImGui::Image(reinterpret_cast<void*>(static_cast<std::intptr_t>(depth_tex_.id())), ImVec2(178, 134));
  } else if (live_.is_bundle) {
    ImGui::TextWrapped("A scene bundle: press Estimate.");
  }
  if (!live_.error.empty()) ImGui::TextColored(ImVec4(1, 0.45f, 0.35f, 1), "%s", live_.error.c_str());
  ImGui::End();
}

void Viewer::PlotConvergence(float width, float height) {
  ImDrawList* dl = ImGui::GetWindowDrawList();
  const ImVec2 p0 = ImGui::GetCursorScreenPos();
  const ImVec2 p1(p0.x + width, p0.y + height);
  dl->AddRectFilled(p0, p1, IM_COL32(25, 27, 32, 255));
  dl->AddRect(p0, p1, IM_COL32(90, 90, 100, 255));
  ImGui::Dummy(ImVec2(width, height));
  if (est_.rows.size() < 1) {
    dl->AddText(ImVec2(p0.x + 8, p0.y + 8), IM_COL32(160, 160, 160, 255), "relative RMSE against run time");
    return;
  }
  double tmax = 0, emin = 1e30, emax = 0;
  for (const ConvergenceRow& r : est_.rows) {
    tmax = std::max(tmax, r.wall_seconds);
    if (r.relative_rmse > 0) emin = std::min(emin, r.relative_rmse), emax = std::max(emax, r.relative_rmse);
  }
  if (!(emax > 0)) return;
  const double lo = std::log10(emin) - 0.05, hi = std::log10(emax) + 0.05;
  auto X = [&](double t) { return p0.x + 30 + static_cast<float>(t / std::max(1e-6, tmax)) * (width - 38); };
  auto Y = [&](double e) {
    return p1.y - 14 - static_cast<float>((std::log10(e) - lo) / std::max(1e-6, hi - lo)) * (height - 22);
  };
  ImVec2 prev;
  int prev_round = -1;
  for (const ConvergenceRow& r : est_.rows) {
    if (!(r.relative_rmse > 0)) continue;
    const ImVec2 p(X(r.wall_seconds), Y(r.relative_rmse));
    if (std::string(r.step) == "trial") {  // (a model's trial solve: a dot, off the line)
      dl->AddCircleFilled(p, 1.5f, IM_COL32(130, 130, 140, 255));
      continue;
    }
    if (prev_round == r.round) dl->AddLine(prev, p, IM_COL32(90, 200, 255, 255), 2);
    else dl->AddCircleFilled(p, 3, IM_COL32(255, 200, 80, 255));  // a round starts
    prev = p;
    prev_round = r.round;
  }
  char label[96];
  std::snprintf(label, sizeof label, "rel. RMSE %.3g .. %.3g (log)", emin, emax);
  dl->AddText(ImVec2(p0.x + 34, p0.y + 3), IM_COL32(200, 200, 200, 255), label);
  std::snprintf(label, sizeof label, "%.1f s", tmax);
  dl->AddText(ImVec2(p1.x - 48, p1.y - 14), IM_COL32(200, 200, 200, 255), label);
  dl->AddText(ImVec2(p0.x + 3, p1.y - 14), IM_COL32(200, 200, 200, 255), "0 s");
}

namespace {

/// A small square of a light's colour (its brightest channel at full scale), the line's
/// text after it.
void Swatch(const std::string& id, const Eigen::Vector3d& rgb) {
  const double peak = std::max(1e-30, rgb.maxCoeff());
  ImGui::ColorButton(id.c_str(),
                     ImVec4(static_cast<float>(rgb.x() / peak), static_cast<float>(rgb.y() / peak),
                            static_cast<float>(rgb.z() / peak), 1.f),
                     ImGuiColorEditFlags_NoTooltip, ImVec2(12, 12));
  ImGui::SameLine();
}

}  // namespace

/// The estimated lamps, suns and glowing surfaces, one line each (world frame, image units).
void Viewer::LightsList() {
  const std::vector<PointLight> lamps = est_.lighting.Of<PointLight>();
  if (!lamps.empty()) {
    ImGui::Text("lamps (point lights), world frame:");
    for (std::size_t k = 0; k < lamps.size(); ++k) {
      const PointLight& l = lamps[k];
      Swatch("##lamp" + std::to_string(k), l.intensity);
      ImGui::Text("(%.2f, %.2f, %.2f) m  I %.3g %.3g %.3g", l.position.x(), l.position.y(), l.position.z(),
                  l.intensity.x(), l.intensity.y(), l.intensity.z());
    }
  }
  const std::vector<DirectionalLight> suns = est_.lighting.Of<DirectionalLight>();
  for (std::size_t k = 0; k < suns.size(); ++k) {
    const DirectionalLight& l = suns[k];
    if (k == 0) ImGui::Text("sun (directional light), towards it in the world frame:");
    ImGui::Text("(%.3f, %.3f, %.3f)  E %.3g %.3g %.3g", l.direction.x(), l.direction.y(), l.direction.z(),
                l.irradiance.x(), l.irradiance.y(), l.irradiance.z());
  }
  const std::vector<EmitterLight> emitters = est_.lighting.Of<EmitterLight>();
  for (std::size_t k = 0; k < emitters.size(); ++k) {
    const EmitterLight& e = emitters[k];
    if (!e.shape) continue;
    if (k == 0) ImGui::Text("glowing surfaces (outlined), centre, area, radiance:");
    Swatch("##emitter" + std::to_string(k), e.radiance);
    const Eigen::Vector3d c = Centroid(*e.shape);
    ImGui::Text("(%.2f, %.2f, %.2f) m  %.3g m^2  L %.3g %.3g %.3g", c.x(), c.y(), c.z(), e.Area(), e.radiance.x(),
                e.radiance.y(), e.radiance.z());
    if (e.in_a_hole) ImGui::Text("  a window's pane over a hole in the mesh");
  }
  const std::size_t openings = est_.result ? est_.result->openings.size() : 0;
  for (std::size_t k = 0; k < openings; ++k) {
    const auto& shape = est_.result->openings[k];
    if (!shape) continue;
    if (k == 0 || !est_.result->openings[k - 1]) ImGui::Text("openings (windows seen through; outlined in blue):");
    const Eigen::Vector3d c = Centroid(*shape);
    ImGui::Text("(%.2f, %.2f, %.2f) m  %.3g m^2", c.x(), c.y(), c.z(), shape->area);
  }
}

/// The estimate's settings (the options of `lightprobe estimate`) for the next Estimate.
void Viewer::EstimateSettings() {
  // The options of the table (estimation/estimate_options.h) that have a label here, each
  // kept within its range.
  for (const EstimateOption& option : EstimateOptionTable()) {
    if (!*option.label) continue;
    const double value = option.get(settings_);
    double next = value;
    if (option.type == EstimateOption::Type::kBool) {
      bool on = value != 0;
      if (ImGui::Checkbox(option.label, &on)) next = on;
    } else if (option.type == EstimateOption::Type::kChoice) {
      std::vector<const char*> names;
      for (const std::string& n : option.names) names.push_back(n.c_str());
      int index = static_cast<int>(value);
      if (ImGui::Combo(option.label, &index, names.data(), static_cast<int>(names.size()))) next = index;
    } else if (option.type == EstimateOption::Type::kInt) {
      int v = static_cast<int>(value);
      if (ImGui::SliderInt(option.label, &v, static_cast<int>(option.ui_min), static_cast<int>(option.ui_max))) next = v;
    } else if (option.ui_min < option.ui_max) {
      float v = static_cast<float>(value);
      if (ImGui::SliderFloat(option.label, &v, static_cast<float>(option.ui_min), static_cast<float>(option.ui_max),
                             "%.1f"))
        next = v;
    } else {
      float v = static_cast<float>(value);
      if (ImGui::InputFloat(option.label, &v, 0, 0, "%.4g")) next = v;
    }
    if (ImGui::IsItemHovered()) ImGui::SetTooltip("%s", option.help);
    const double lowest = option.min_exclusive ? option.min + 1e-6 : option.min;
    next = std::min(std::max(next, lowest), option.max);
    if (next != value) option.set(&settings_, next);
  }
}

void Viewer::PanelEstimate() {
  int win_w, win_h;
  glfwGetWindowSize(window_, &win_w, &win_h);
  ImGui::SetNextWindowPos(ImVec2(0, 330));
  ImGui::SetNextWindowSize(ImVec2(kPanelWidth, static_cast<float>(win_h) - 330));
  ImGui::Begin("Estimate", nullptr, ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse);
  const bool running = est_.state == EstimateState::kRunning || est_.state == EstimateState::kPreparing;
  if (ImGui::Button("Estimate", ImVec2(100, 0))) {
    session_.Estimate(settings_);
    if (live_.live_estimation) session_.SetLive(true, settings_);  // the live ones take these settings too
  }
  ImGui::SameLine();
  bool live = live_.live_estimation;
  if (ImGui::Checkbox("live", &live)) session_.SetLive(live, settings_);
  if (ImGui::IsItemHovered())
    ImGui::SetTooltip("estimate by itself while the scan grows, each estimate warm-started from the last");
  ImGui::SameLine();
  if (running && ImGui::Button("Cancel")) session_.CancelEstimate();
  if (!running) {
    ImGui::SameLine();
    ImGui::SetNextItemWidth(140);
    ImGui::InputText("##export", export_field_, sizeof export_field_);
    ImGui::SameLine();
    const bool exporting = est_.export_state == ExportState::kExporting;
    if (!exporting && ImGui::Button("Export") && est_.result) {
      std::vector<ExportFormat> formats;
      for (ExportFormat f : {ExportFormat::kBlender, ExportFormat::kGltf, ExportFormat::kSh})
        if (export_formats_[static_cast<int>(f)]) formats.push_back(f);
      session_.Export(export_field_, formats);
    }
    // Besides the scene and the estimate: the formats of `lightprobe export`, each into DIR/<format>.
    ImGui::Checkbox("Blender", &export_formats_[0]);
    ImGui::SameLine();
    ImGui::Checkbox("glTF", &export_formats_[1]);
    ImGui::SameLine();
    ImGui::Checkbox("SH", &export_formats_[2]);
  }
  char overlay[64];
  std::snprintf(overlay, sizeof overlay, "%s %.0f%%", ToString(est_.state), 100 * est_.progress);
  ImGui::ProgressBar(static_cast<float>(est_.progress), ImVec2(-1, 0), overlay);
  ImGui::TextWrapped("%s", est_.message.c_str());
  if (!std::isnan(est_.seconds_to_map) && std::isnan(est_.seconds_to_first))
    ImGui::Text("the map after %.2f s (round 1 seeks lamps)", est_.seconds_to_map);
  if (!std::isnan(est_.seconds_to_first))
    ImGui::Text("%sfirst round after %.2f s%s",
                std::isnan(est_.seconds_to_map) ? "" : ("the map after " + std::to_string(est_.seconds_to_map).substr(0, 4) + " s, ").c_str(),
                est_.seconds_to_first,
                std::isnan(est_.seconds_total) ? "" : (", done after " + std::to_string(est_.seconds_total).substr(0, 5) + " s").c_str());
  if (est_.live)
    ImGui::Text("live estimate %d (%s%s)%s", est_.live_index, est_.preview ? "preview, " : "", est_.warm ? "warm" : "cold",
                std::isnan(est_.finished_at)
                    ? ""
                    : (", the one shown from " + std::to_string(session_.seconds() - est_.finished_at).substr(0, 4) +
                       " s ago").c_str());
  PlotConvergence(kPanelWidth - 16, 110);
  LightsList();
  if (!est_.export_message.empty()) ImGui::TextWrapped("%s", est_.export_message.c_str());
  if (ImGui::CollapsingHeader("Settings")) EstimateSettings();
  ImGui::End();
}

void Viewer::PanelEnvironment() {
  int win_w, win_h;
  glfwGetWindowSize(window_, &win_w, &win_h);
  env_rect_ = {kPanelWidth, static_cast<float>(win_h) - kEnvHeight, static_cast<float>(win_w) - kPanelWidth, kEnvHeight};
  ImGui::SetNextWindowPos(ImVec2(env_rect_.x, env_rect_.y));
  ImGui::SetNextWindowSize(ImVec2(env_rect_.w, env_rect_.h));
  ImGui::Begin("Environment map", nullptr,
               ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse);
  if (est_.env && est_.version != env_version_ && !est_.lighting.map.empty()) {
    env_version_ = est_.version;
    env_tex_.Upload(EnvDisplay(*est_.env, est_.lighting.map, 128));
  }
  const float h = env_rect_.h - 50, w = 2 * h;
  ImVec2 at = ImGui::GetCursorScreenPos();
  equirect_rect_ = {at.x, at.y, w, h};
  if (est_.env && env_tex_.width() > 0) {
    ImGui::Image(reinterpret_cast<void*>(static_cast<std::intptr_t>(env_tex_.id())), ImVec2(w, h));
    // The dominant directions on the picture.
    ImDrawList* dl = ImGui::GetWindowDrawList();
    for (const Eigen::Vector3d& d : est_.dominant) {
      double theta, phi;
      est_.env->ToSpherical(d, &theta, &phi);
      const ImVec2 p(at.x + static_cast<float>(phi / (2 * M_PI)) * w, at.y + static_cast<float>(theta / M_PI) * h);
      dl->AddCircle(p, 8, IM_COL32(255, 230, 30, 255), 16, 2);
    }
  } else {
    ImGui::Dummy(ImVec2(w, h));
    ImGui::GetWindowDrawList()->AddRect(at, ImVec2(at.x + w, at.y + h), IM_COL32(90, 90, 100, 255));
    ImGui::GetWindowDrawList()->AddText(ImVec2(at.x + 8, at.y + 8), IM_COL32(160, 160, 160, 255),
                                        "no estimate yet: press Estimate");
  }
  ImGui::SameLine();
  // The discrete directions on a sphere seen from the 3D view's camera, coloured by intensity.
  at = ImGui::GetCursorScreenPos();
  sphere_rect_ = {at.x, at.y, h, h};
  ImGui::Dummy(ImVec2(h, h));
  ImDrawList* dl = ImGui::GetWindowDrawList();
  const ImVec2 c(at.x + h / 2, at.y + h / 2);
  const float radius = h / 2 - 4;
  dl->AddCircle(c, radius, IM_COL32(90, 90, 100, 255), 48);
  if (est_.env && !est_.lighting.map.empty()) {
    const Eigen::Matrix4f v = camera_.View();
    const Eigen::Vector3f right = v.block<1, 3>(0, 0).transpose(), up = v.block<1, 3>(1, 0).transpose(),
                          back = v.block<1, 3>(2, 0).transpose();
    double top = 0;
    for (int j = 0; j < est_.env->size(); ++j)
      top = std::max(top, Luminance(est_.lighting.map[3 * j], est_.lighting.map[3 * j + 1], est_.lighting.map[3 * j + 2]));
    for (int j = 0; j < est_.env->size(); ++j) {
      const Eigen::Vector3f d = est_.env->direction(j).cast<float>();
      const float depth = d.dot(back);  // towards the viewer: front hemisphere
      const ImVec2 p(c.x + radius * d.dot(right), c.y - radius * d.dot(up));
      const double lum = Luminance(est_.lighting.map[3 * j], est_.lighting.map[3 * j + 1], est_.lighting.map[3 * j + 2]);
      const Eigen::Vector3f col = Heat(top > 0 ? static_cast<float>(std::sqrt(lum / top)) : 0.f);
      const int alpha = depth >= 0 ? 255 : 70;
      dl->AddCircleFilled(p, depth >= 0 ? 3.f : 2.f,
                          IM_COL32(int(255 * col.x()), int(255 * col.y()), int(255 * col.z()), alpha));
    }
    for (const Eigen::Vector3d& dd : est_.dominant) {
      const Eigen::Vector3f d = dd.cast<float>();
      dl->AddCircle(ImVec2(c.x + radius * d.dot(right), c.y - radius * d.dot(up)), 8, IM_COL32(255, 230, 30, 255), 16,
                    2);
    }
  }
  ImGui::Text("directions: %d (%d rings); dominant light(s) circled; drag the 3D view to turn the sphere",
              est_.env ? est_.env->size() : 0, est_.env ? est_.env->rings() : 0);
  const bool map_dark = std::all_of(est_.lighting.map.begin(), est_.lighting.map.end(), [](double v) { return v <= 0; });
  const std::size_t lamps = est_.lighting.Count<PointLight>();
  if (map_dark && lamps > 0)
    ImGui::Text("the map is dark: the light comes from the %zu lamp(s) drawn in the 3D view", lamps);
  ImGui::End();
}

void Viewer::PanelKeyframe() {
  if (selected_keyframe_ < 0 || !est_.scene || selected_keyframe_ >= static_cast<int>(est_.scene->views.size()))
    return;
  const View& view = est_.scene->views[selected_keyframe_];
  // The clean render once it has a pass, else the fit.
  const std::vector<ImageRGB>* renders = est_.renders ? est_.renders.get() : est_.result ? &est_.result->renders : nullptr;
  const bool have_render = renders && selected_keyframe_ < static_cast<int>(renders->size());
  const std::uint64_t version = (est_.version * 4096 + est_.render_version) * 2 + (have_render ? 1 : 0);
  if (compare_keyframe_ != selected_keyframe_ || compare_version_ != version) {
    compare_keyframe_ = selected_keyframe_;
    compare_version_ = version;
    // As render_view*.png and error_view*.png: the reference's white level maps to white.
    const float white = WhiteLevel(view);
    compare_tex_[0].Upload(EncodeSrgb8(view.image, 1 / white));
    if (have_render) {
      const ImageRGB& render = (*renders)[selected_keyframe_];
      compare_tex_[1].Upload(EncodeSrgb8(render, 1 / white));
      compare_tex_[2].Upload(Heatmap(render.width, render.height, ErrorImage(render, view), kErrorDisplayFraction * white));
    }
  }
  int win_w, win_h;
  glfwGetWindowSize(window_, &win_w, &win_h);
  ImGui::SetNextWindowPos(ImVec2(kPanelWidth + 10, 40), ImGuiCond_Appearing);
  bool open = true;
  ImGui::Begin("Keyframe", &open, ImGuiWindowFlags_AlwaysAutoResize);
  ImGui::Text("keyframe %d: reference | relit by the estimate | error (0 .. 25 %% of white)", selected_keyframe_);
  if (est_.renders)
    ImGui::Text("relit: clean render, %d samples per pixel, noise %.1f %%", est_.render_samples, 100 * est_.render_noise);
  else if (have_render && est_.options.render_spp > 0)
    ImGui::Text("relit: traced at %d samples per pixel", est_.options.render_spp);
  else if (have_render)
    ImGui::Text(est_.options.render_noise > 0 ? "relit: the fit (the clean render follows the lit shading)"
                                              : "relit: the fit");
  const float w = 240, h = w * view.camera.height / std::max(1, view.camera.width);
  ImGui::Image(reinterpret_cast<void*>(static_cast<std::intptr_t>(compare_tex_[0].id())), ImVec2(w, h));
  if (have_render) {
    for (int k = 1; k < 3; ++k) {
      ImGui::SameLine();
      ImGui::Image(reinterpret_cast<void*>(static_cast<std::intptr_t>(compare_tex_[k].id())), ImVec2(w, h));
    }
  } else {
    ImGui::SameLine();
    ImGui::TextWrapped("the relit render comes with the finished estimate");
  }
  ImGui::End();
  if (!open) selected_keyframe_ = -1;
}

/// The shading mode bar over the 3D view.
void Viewer::ShadingBar() {
  ImGui::SetNextWindowPos(ImVec2(view_rect_.x + 8, 8));
  ImGui::SetNextWindowBgAlpha(0.6f);
  ImGui::Begin("##shading", nullptr,
               ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_AlwaysAutoResize | ImGuiWindowFlags_NoMove);
  for (Shading s : {Shading::kAlbedo, Shading::kLit, Shading::kError, Shading::kNormals}) {
    if (ImGui::RadioButton(ToString(s), shading_ == s)) shading_ = s;
    ImGui::SameLine();
  }
  if (ImGui::Button("reset view")) ResetCamera();
  if (shading_ == Shading::kLit) {
    ImGui::SetNextItemWidth(120);
    ImGui::SliderFloat("exposure", &exposure_, 0.1f, 8.f, "%.2f", ImGuiSliderFlags_Logarithmic);
    ImGui::SameLine();
    ImGui::Text("%d samples/vertex, noise %.1f %%", est_.lit_samples, 100 * est_.lit_noise);
  } else if (shading_ == Shading::kAlbedo) {
    ImGui::Checkbox("headlight", &headlight_);
  }
  if ((shading_ == Shading::kLit || shading_ == Shading::kError) && !est_.lit)
    ImGui::Text("(available once an estimate is done)");
  ImGui::Text("%zu triangles, %.0f frames/s", mesh_.triangles(), ImGui::GetIO().Framerate);
  ImGui::End();
}

/// One step of the command file, if one runs (an error ends the window with exit code 1).
void Viewer::StepScript() {
  if (script_ && !quit_) {
    try {
      if (!script_->Step()) script_.reset();
    } catch (const std::exception& e) {
      std::fprintf(stderr, "lightprobe: script: %s\n", e.what());
      exit_code_ = 1;
      quit_ = true;
    }
  }
}

bool Viewer::Frame() {
  const double now = glfwGetTime();
  if (last_frame_time_ > 0) {
    if (bench_frames_left_ > 0) {
      bench_seconds_.push_back(now - last_frame_time_);
      if (--bench_frames_left_ == 0) bench_scene_renders_end_ = scene_renders_;
    }
  }
  last_frame_time_ = now;
  // The workers share the cores with the window (Mesa renders on the CPU): outside the
  // benchmark at most ~60 frames/s, and ~10 when nothing changed (any input wakes it). An
  // estimate's convergence rows (hundreds a second) are shown at that ~10: drawn at 60 a
  // second the window took a quarter of the estimate's two cores (the demo's first round
  // shown 2.1-2.4 s after the press, the estimate 11.6-12.1 s, against 10.1 s headless).
  if (bench_frames_left_ > 0) glfwPollEvents();
  else glfwWaitEventsTimeout(changed_ ? 1.0 / 60 : 0.1);
  live_ = session_.live();
  est_ = session_.estimate();
  const std::array<std::uint64_t, 5> versions = {live_.frame_version, live_.model_version, est_.version,
                                                 est_.lit_version, static_cast<std::uint64_t>(est_.state)};
  changed_ = versions != versions_ || dragging_ || ImGui::IsAnyItemActive();
  versions_ = versions;
  SyncModel();
  SyncShading();

  ImGui_ImplOpenGL3_NewFrame();
  ImGui_ImplGlfw_NewFrame();
  ImGui::NewFrame();
  int win_w, win_h;
  glfwGetWindowSize(window_, &win_w, &win_h);
  view_rect_ = {kPanelWidth, 0, static_cast<float>(win_w) - kPanelWidth, static_cast<float>(win_h) - kEnvHeight};
  PanelSource();
  PanelEstimate();
  PanelEnvironment();
  PanelKeyframe();
  ShadingBar();
  HandleMouse(view_rect_);
  if (bench_orbit_ && bench_frames_left_ > 0) camera_.yaw += 0.01f;
  moving_ = dragging_ || ImGui::GetIO().MouseWheel != 0 || (bench_orbit_ && bench_frames_left_ > 0);

  // The 3D view is drawn offscreen only when something in it changed (Mesa rasterizes on
  // the CPU the estimator also needs), and shown as an image every frame.
  const std::string key = SceneKey(view_rect_);
  if (key != scene_key_) {
    DrawScene(view_rect_);
    scene_key_ = key;
  }
  ImGui::GetBackgroundDrawList()->AddImage(reinterpret_cast<void*>(static_cast<std::intptr_t>(target_.texture())),
                                           ImVec2(view_rect_.x, view_rect_.y),
                                           ImVec2(view_rect_.x + view_rect_.w, view_rect_.y + view_rect_.h),
                                           ImVec2(0, 1), ImVec2(1, 0));

  StepScript();

  ImGui::Render();
  int fb_w, fb_h;
  glfwGetFramebufferSize(window_, &fb_w, &fb_h);
  glViewport(0, 0, fb_w, fb_h);
  glClearColor(0.1f, 0.1f, 0.11f, 1.f);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
  if (!pending_screenshot_.empty()) {
    WriteRgb8Png(pending_screenshot_, ReadBackBuffer(fb_w, fb_h));
    pending_screenshot_.clear();
  }
  glfwSwapBuffers(window_);
  return !quit_ && !glfwWindowShouldClose(window_);
}

void Viewer::Screenshot(const std::string& path) { pending_screenshot_ = path; }

namespace {

/// This process's resident memory now (Linux /proc/self/statm), MiB; 0 where unknown.
double ResidentMegabytes() {
  std::ifstream statm("/proc/self/statm");
  double pages = 0, resident = 0;
  if (!(statm >> pages >> resident)) return 0;
  return resident * static_cast<double>(sysconf(_SC_PAGESIZE)) / 1048576.0;
}

}  // namespace

/// The estimate's part of WriteState: its state, progress, timings, and the live switch's.
nlohmann::json Viewer::EstimateStateJson() const {
  using nlohmann::json;
  return {{"state", ToString(est_.state)},
          {"message", est_.message},
          {"rows", est_.rows.size()},
          {"rounds", est_.result ? est_.result->rounds.size() : 0},
          {"albedo_refined", est_.result && !est_.result->albedo.empty()},
          {"albedo_shading_refined", shading_ == Shading::kAlbedo && shown_refined_albedo_},
          {"lit_samples", est_.lit_samples},
          {"lit_noise", std::isnan(est_.lit_noise) ? json() : json(est_.lit_noise)},
          {"seconds_to_map", std::isnan(est_.seconds_to_map) ? json() : json(est_.seconds_to_map)},
          {"seconds_to_first", std::isnan(est_.seconds_to_first) ? json() : json(est_.seconds_to_first)},
          {"seconds_total", std::isnan(est_.seconds_total) ? json() : json(est_.seconds_total)},
          {"export", est_.export_message},
          {"export_state", ToString(est_.export_state)},
          {"live", est_.live},
          {"live_index", est_.live_index},
          {"preview", est_.preview},
          {"warm", est_.warm},
          {"has_result", est_.HasOwnResult()},
          {"age_seconds", std::isnan(est_.finished_at) ? json() : json(session_.seconds() - est_.finished_at)}};
}

/// The glowing surfaces ("emitters") and the openings as the 3D view outlines them.
void Viewer::SurfacesState(nlohmann::json* estimate) const {
  using nlohmann::json;
  auto vec = [](const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); };
  (*estimate)["emitters"] = json::array();
  for (const EmitterLight& e : est_.lighting.Of<EmitterLight>())
    if (e.shape)
      (*estimate)["emitters"].push_back({{"id", e.id}, {"radiance", vec(e.radiance)}, {"area", e.Area()},
                                         {"centroid", vec(Centroid(*e.shape))},
                                         {"outline_edges", OutlineOf(e.shape).size()}, {"in_a_hole", e.in_a_hole}});
  (*estimate)["openings"] = json::array();
  if (est_.result)
    for (const auto& shape : est_.result->openings)
      if (shape)
        (*estimate)["openings"].push_back({{"area", shape->area}, {"centroid", vec(Centroid(*shape))},
                                           {"outline_edges", OutlineOf(shape).size()}});
}

void Viewer::WriteState(const std::string& path) const {
  using nlohmann::json;
  auto rect = [](const Rect& r) { return json::array({r.x, r.y, r.w, r.h}); };
  json j;
  j["window"] = {{"view3d", rect(view_rect_)},  {"environment", rect(env_rect_)}, {"equirect", rect(equirect_rect_)},
                 {"sphere", rect(sphere_rect_)}, {"live", rect(live_rect_)}};
  j["source"] = live_.source;
  j["error"] = live_.error;
  j["frames_read"] = live_.frames_read;
  j["frames_tracked"] = live_.frames_tracked;
  j["frames_lost"] = live_.frames_lost;
  j["record"] = {
      {"recording", live_.recording}, {"recorded_frames", live_.recorded_frames}, {"message", live_.record_message}};
  j["model_triangles"] = live_.model ? live_.model->triangles.size() : 0;
  j["shown_triangles"] = mesh_.triangles();
  j["shading"] = ToString(shading_);
  j["estimate"] = EstimateStateJson();
  j["seconds"] = session_.seconds();  // the session's clock
  j["dropped"] = live_.dropped;
  j["rss_mb"] = ResidentMegabytes();
  j["live_estimation"] = live_.live_estimation;
  j["live_estimates"] = live_.live_estimates;
  if (est_.result && !std::isnan(est_.result->final_angular_error_deg))
    j["estimate"]["angular_error_deg"] = est_.result->final_angular_error_deg;
  // Where the panels must show the estimate: its dominant directions (world) and the map's
  // frame (docs/formats.md's convention), for a test to compute the pixels by hand.
  auto vec = [](const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); };
  j["estimate"]["dominant"] = json::array();
  for (const Eigen::Vector3d& d : est_.dominant) j["estimate"]["dominant"].push_back(vec(d));
  // The lamps, and how the 3D view projects the world (column-major, to NDC over view3d).
  // Each light's 95 % region as the 3D view draws it (semi-axes ascending, m or radians;
  // their directions as columns), when the finished estimate has one.
  const auto with_region = [&](json entry, std::size_t k) {
    Eigen::Vector3d semi;
    Eigen::Matrix3d axes;
    if (const LightUncertainty* u = UncertaintyOf(k);
        u && Region95(u->shape_covariance, ShapeDims(est_.lighting.lights[k]), &semi, &axes))
      entry["region_95"] = {{"semi_axes", vec(semi)}, {"axes", {vec(axes.col(0)), vec(axes.col(1)), vec(axes.col(2))}}};
    return entry;
  };
  j["estimate"]["point_lights"] = json::array();
  j["estimate"]["directional_lights"] = json::array();  // and where the 3D view draws each
  SurfacesState(&j["estimate"]);
  for (std::size_t k = 0; k < est_.lighting.lights.size(); ++k) {
    if (const PointLight* l = std::get_if<PointLight>(&est_.lighting.lights[k]))
      j["estimate"]["point_lights"].push_back(
          with_region({{"position", vec(l->position)}, {"intensity", vec(l->intensity)}}, k));
    if (const DirectionalLight* l = std::get_if<DirectionalLight>(&est_.lighting.lights[k]))
      j["estimate"]["directional_lights"].push_back(with_region({{"direction", vec(l->direction)},
                                                                 {"irradiance", vec(l->irradiance)},
                                                                 {"angular_radius", l->angular_radius},
                                                                 {"marker", vec(SunMarkerCentre(*l).cast<double>())},
                                                                 {"marker_radius", sun_marker_size_}},
                                                                k));
  }
  j["view3d_projection"] = std::vector<float>(view_projection_.data(), view_projection_.data() + 16);
  j["orbit_target"] = vec(camera_.target.cast<double>());
  if (est_.env)
    j["estimate"]["env_frame"] = {
        {"up", vec(est_.env->up())}, {"frame_x", vec(est_.env->frame_x())}, {"frame_y", vec(est_.env->frame_y())}};
  if (!bench_seconds_.empty()) {
    std::vector<double> s = bench_seconds_;
    std::sort(s.begin(), s.end());
    double sum = 0;
    for (double v : s) sum += v;
    j["bench"] = {{"frames", s.size()},
                  {"mean_ms", 1000 * sum / s.size()},
                  {"median_ms", 1000 * s[s.size() / 2]},
                  {"p95_ms", 1000 * s[std::min(s.size() - 1, s.size() * 95 / 100)]},
                  {"fps", s.size() / sum},
                  {"orbit", bench_orbit_},
                  {"scene_renders", bench_scene_renders_end_ - bench_scene_renders_start_}};
  }
  std::ofstream(path) << j.dump(2) << "\n";
}

int RunViewer(const ViewerOptions& options) {
  glfwSetErrorCallback(OnGlfwError);
  bool ok = glfwInit();
  // With a display named, a failure can be an X server resetting as its last client left
  // (Xvfb between two windows): try again briefly before saying there is none.
  const char* display = std::getenv("DISPLAY");
  for (int attempt = 0; !ok && display && *display && attempt < 5; ++attempt) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    ok = glfwInit();
  }
  if (!ok)
    throw InputError("cannot open a window (no display: " + (g_glfw_error.empty() ? "glfwInit failed" : g_glfw_error) +
                     "); run the pipeline without one: lightprobe --headless INPUT --out DIR");
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  GLFWwindow* window = glfwCreateWindow(options.width, options.height, "lightprobe", nullptr, nullptr);
  if (!window) {
    glfwTerminate();
    throw InputError("cannot create an OpenGL 3.3 window (" + g_glfw_error +
                     "); run the pipeline without one: lightprobe --headless INPUT --out DIR");
  }
  glfwMakeContextCurrent(window);
  glfwSwapInterval(0);  // the benchmark measures frame time, not the display's refresh
  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ImGui::GetIO().IniFilename = nullptr;  // no imgui.ini in the working directory
  ImGui::StyleColorsDark();
  ImGui_ImplGlfw_InitForOpenGL(window, true);
  ImGui_ImplOpenGL3_Init("#version 330 core");
  int code = 0;
  try {
    Viewer viewer(options, window);
    while (viewer.Frame()) {
    }
    code = viewer.exit_code();
  } catch (...) {
    ImGui_ImplOpenGL3_Shutdown();
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
    glfwDestroyWindow(window);
    glfwTerminate();
    throw;
  }
  ImGui_ImplOpenGL3_Shutdown();
  ImGui_ImplGlfw_Shutdown();
  ImGui::DestroyContext();
  glfwDestroyWindow(window);
  glfwTerminate();
  return code;
}

}  // namespace lp::ui
