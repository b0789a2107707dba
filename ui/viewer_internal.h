#pragma once
/// Inside the viewer (ui/ only): the window's state, shared by viewer.cpp (panels, 3D
/// view) and script.cpp (the command file).
#include <array>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "ui/gl.h"
#include "ui/script_syntax.h"
#include "ui/session.h"
#include "ui/viewer.h"

namespace lp::ui {

enum class Shading { kAlbedo, kLit, kError, kNormals };
const char* ToString(Shading s);

/// Orbit camera around a target; `up` is the scene's up.
struct OrbitCamera {
  Eigen::Vector3f target = Eigen::Vector3f::Zero();
  Eigen::Vector3f up = -Eigen::Vector3f::UnitY();
  float yaw = 0.6f, pitch = 0.5f, distance = 3.f;
  Eigen::Vector3f Eye() const;
  /// The horizontal axes yaw is measured in: yaw 0 along `a`, pi/2 along `b`.
  void Horizontal(Eigen::Vector3f* a, Eigen::Vector3f* b) const;
  Eigen::Matrix4f View() const;
  Eigen::Matrix4f Projection(float aspect) const;
};

/// A rectangle in window pixels (top-left origin).
struct Rect {
  float x = 0, y = 0, w = 0, h = 0;
  bool Contains(float px, float py) const { return px >= x && py >= y && px < x + w && py < y + h; }
};

/// The script commands that have no handler in script.cpp (empty: checked by a test).
std::vector<std::string> UnhandledScriptCommands();

class Viewer {
 public:
  Viewer(const ViewerOptions& options, GLFWwindow* window);
  ~Viewer();
  /// One frame: poll, panels, 3D view, script step, swap. False when the window should close.
  bool Frame();
  int exit_code() const { return exit_code_; }

 private:
  friend class ScriptRunner;
  void SyncModel();
  /// The estimate's scene mesh as drawn: with the finished estimate's openings (windows seen
  /// through) left out, built once per result; the snapshot's own mesh when it has none.
  std::shared_ptr<const Mesh> SnapshotMesh();
  std::shared_ptr<const EstimateResult> opened_for_;
  std::shared_ptr<const Mesh> opened_mesh_;
  void SyncShading();
  void DrawScene(const Rect& r);
  void AddLightMarkers(float size);
  void AddLampMarkers(float size);
  void AddEmitterOutlines();
  /// Each opening's outline in sky blue, a centimetre off its surface on both sides.
  void AddOpeningOutlines();
  /// An emitter's outline (Outline), computed once per shape: drawn every frame.
  const std::vector<OutlineEdge>& OutlineOf(const std::shared_ptr<const EmitterShape>& shape) const;
  mutable std::map<std::shared_ptr<const EmitterShape>, std::vector<OutlineEdge>> outlines_;
  /// Light k of est_.lighting's uncertainty, when the finished estimate shown has one
  /// (null while an estimate runs, or where it does not).
  const LightUncertainty* UncertaintyOf(std::size_t k) const;
  /// The 95 % region of each light: a lamp's ellipsoid (its three principal ellipses), a
  /// directional light's cone (an ellipse around its marker), in the light's colour dimmed.
  void AddRegions();
  void AddSunMarkers(float size);
  Eigen::Vector3f SunMarkerCentre(const DirectionalLight& l) const;
  float sun_marker_size_ = 0;  ///< the radius (world units) of the suns' rings last drawn
  std::string SceneKey(const Rect& r) const;
  void HandleMouse(const Rect& r);
  void PanelSource();
  void PanelEstimate();
  void LightsList();
  void EstimateSettings();
  void ShadingBar();
  void StepScript();
  void PanelEnvironment();
  void PanelKeyframe();
  void PlotConvergence(float width, float height);
  void ResetCamera();
  void WriteState(const std::string& path) const;
  nlohmann::json EstimateStateJson() const;
  void SurfacesState(nlohmann::json* estimate) const;
  void Screenshot(const std::string& path);

  ViewerOptions options_;
  GLFWwindow* window_;
  Session session_;
  LiveStatus live_;
  EstimateStatus est_;
  EstimateOptions settings_;

  Program mesh_program_;
  Program line_program_;
  GlMesh mesh_;
  GlMesh coarse_mesh_;  // drawn while the view moves
  std::vector<int> cluster_of_;
  bool has_coarse_ = false, moving_ = false;
  GlLines lines_;
  RenderTarget target_;
  std::string scene_key_;
  std::uint64_t scene_renders_ = 0;
  Texture color_tex_, depth_tex_, env_tex_;
  std::array<Texture, 3> compare_tex_;  // reference, render, error of the selected keyframe
  std::uint64_t model_version_ = ~0ull, frame_version_ = ~0ull, env_version_ = ~0ull, lit_version_ = ~0ull;
  bool shown_refined_albedo_ = false;  ///< the albedo shading shows the estimate's refined albedo
  std::shared_ptr<const Mesh> shown_mesh_;   // geometry in mesh_
  bool showing_snapshot_ = false;            // mesh_ holds the estimate's scene mesh
  Shading shading_ = Shading::kAlbedo, shaded_ = Shading::kAlbedo;
  bool headlight_ = true;
  float exposure_ = 1.f;
  OrbitCamera camera_;
  Eigen::Matrix4f view_projection_ = Eigen::Matrix4f::Identity();  ///< the 3D view's, last drawn
  bool camera_set_ = false;
  Rect view_rect_, env_rect_, equirect_rect_, sphere_rect_, live_rect_;
  int selected_keyframe_ = -1, compare_keyframe_ = -1;
  std::uint64_t compare_version_ = ~0ull;
  bool dragging_ = false, drag_moved_ = false;
  double drag_x_ = 0, drag_y_ = 0;
  char path_field_[512] = {0};
  char record_field_[512] = "lightprobe-recording.oni";
  float record_seconds_ = 10;
  char export_field_[512] = "lightprobe-export";
  bool export_formats_[3] = {false, false, false};  // blender, gltf, sh (ExportFormat's order)
  float seek_frame_ = 0;
  float speed_ = 1.f;

  // Frame timing (the benchmark) and the script.
  bool changed_ = true;
  std::array<std::uint64_t, 5> versions_{};
  double last_frame_time_ = 0;
  int bench_frames_left_ = 0;
  std::vector<double> bench_seconds_;
  bool bench_orbit_ = false;
  std::uint64_t bench_scene_renders_start_ = 0, bench_scene_renders_end_ = 0;
  std::unique_ptr<class ScriptRunner> script_;
  int exit_code_ = 0;
  bool quit_ = false;
  std::string pending_screenshot_;
};

/// Runs the command file one step per frame (commands that wait return false until done).
class ScriptRunner {
 public:
  /// Throws InputError for a missing file or an unknown command (checked up front).
  ScriptRunner(const std::string& path, Viewer* viewer);
  /// Advances; returns false when the script is finished.
  bool Step();

 private:
  bool Run(const ScriptLine& line);  ///< true = done with this line
  [[noreturn]] void Fail(const ScriptLine& line, const std::string& why) const;
  std::string path_;
  Viewer* viewer_;
  std::vector<ScriptLine> lines_;
  std::size_t next_ = 0;
  double line_started_ = -1;
  int frames_waited_ = 0;
  std::int64_t line_frames_read_ = 0;  ///< the live panel's frames read when the line started
};

}  // namespace lp::ui
