#include "exports/blender.h"

#include <algorithm>
#include <cstdio>
#include <sstream>

#include "common/atomic_file.h"
#include "common/image_io.h"
#include "exports/axes.h"

namespace lp {
namespace fs = std::filesystem;
namespace {
constexpr double kPi = 3.14159265358979323846;

std::string Num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

std::string List(const Eigen::Vector3d& v) { return "[" + Num(v.x()) + ", " + Num(v.y()) + ", " + Num(v.z()) + "]"; }

std::string Rows(const Eigen::MatrixXd& m) {
  std::string s = "[";
  for (int r = 0; r < m.rows(); ++r) {
    s += r ? ", [" : "[";
    for (int c = 0; c < m.cols(); ++c) s += (c ? ", " : "") + Num(m(r, c));
    s += "]";
  }
  return s + "]";
}

/// scene.py's data block: Python literals in Blender's frame (the mesh's rotation aside).
std::string DataBlock(const ExportScene& s, bool has_world) {
  const ExportAxes axes(s.up);
  const Eigen::Matrix3d& R = axes.blender_from_world;
  std::ostringstream py;
  py << "# Written by `lightprobe export --format blender` (docs/formats.md, \"Exports\").\n"
     << "# Builds the estimate's scene in Blender (Cycles):\n"
     << "#   blender -b -noaudio --factory-startup --python scene.py -- [--save FILE.blend]\n"
     << "#       [--render FILE.exr] [--camera K] [--samples N] [--seed N]\n"
     << "# or, from Blender's own window, Scripting > Open > Run Script. Everything below is in\n"
     << "# Blender's frame (+Z up); mesh.ply is in the bundle's and is turned by BLENDER_FROM_WORLD.\n"
     << "MESH = \"mesh.ply\"\n"
     << "WORLD = " << (has_world ? "\"world.exr\"" : "None") << "\n"
     << "BLENDER_FROM_WORLD = " << Rows(R) << "\n"
     << "# Point lights: power P (W) from the radiant intensity I (W/sr): P = 4 pi I (Cycles'\n"
     << "# point light of power P emits P / 4 pi per steradian); colour x power per channel.\n"
     << "POINT_LIGHTS = [\n";
  for (const PointLight& l : OfKind<PointLight>(s.lights)) {
    Eigen::Vector3d colour;
    const double i = SplitColour(l.intensity, &colour);
    py << "    {\"location\": " << List(R * l.position) << ", \"color\": " << List(colour)
       << ", \"power\": " << Num(4 * kPi * i) << ", \"radius\": " << Num(l.radius) << "},\n";
  }
  py << "]\n"
     << "# Suns: strength = irradiance (W/m^2) on a surface facing the sun; angle = twice the\n"
     << "# angular radius; \"direction\" points towards the sun.\n"
     << "SUNS = [\n";
  for (const DirectionalLight& d : OfKind<DirectionalLight>(s.lights)) {
    Eigen::Vector3d colour;
    const double e = SplitColour(d.irradiance, &colour);
    py << "    {\"direction\": " << List(R * d.direction) << ", \"color\": " << List(colour)
       << ", \"strength\": " << Num(e) << ", \"angle\": " << Num(2 * d.angular_radius) << "},\n";
  }
  py << "]\n"
     << "# Glowing surfaces: emission strength x colour = the radiance (W/(m^2 sr)) on the side that\n"
     << "# emits; each triangle's corners (x, y, z three times), lifted 2 mm off the mesh on that side.\n"
     << "EMITTERS = [\n";
  for (const EmitterLight& e : OfKind<EmitterLight>(s.lights)) {
    if (!e.shape) continue;
    Eigen::Vector3d colour;
    const double strength = SplitColour(e.radiance, &colour);
    py << "    {\"color\": " << List(colour) << ", \"strength\": " << Num(strength) << ", \"triangles\": [";
    const EmitterShape& sh = *e.shape;
    for (std::size_t t = 0; t < sh.a.size(); ++t) {
      const Eigen::Vector3d lift = 0.002 * sh.normal[t].cast<double>();
      for (const Eigen::Vector3f& corner : {sh.a[t], sh.b[t], sh.c[t]}) {
        const Eigen::Vector3d p = R * (corner.cast<double>() + lift);
        py << Num(p.x()) << ", " << Num(p.y()) << ", " << Num(p.z()) << ", ";  // (Python takes the last comma)
      }
    }
    py << "],\n     \"normal_side\": [";
    for (std::size_t t = 0; t < sh.a.size(); ++t) {
      const bool along = (sh.b[t] - sh.a[t]).cross(sh.c[t] - sh.a[t]).dot(sh.normal[t]) >= 0;
      py << (along ? "1, " : "0, ");
    }
    py << "]},\n";
  }
  py << "]\n"
     << "# One camera per keyframe (keyframe 0 active): Blender's camera looks down its -Z, +Y up.\n"
     << "CAMERAS = [\n";
  for (const Camera& c : s.cameras) {
    const BlenderCamera b = ToBlenderCamera(c, R);
    py << "    {\"width\": " << b.width << ", \"height\": " << b.height << ", \"lens\": " << Num(b.lens_mm)
       << ", \"sensor_width\": " << Num(b.sensor_width_mm) << ", \"shift_x\": " << Num(b.shift_x)
       << ", \"shift_y\": " << Num(b.shift_y) << ", \"pixel_aspect_x\": " << Num(b.pixel_aspect_x)
       << ", \"pixel_aspect_y\": " << Num(b.pixel_aspect_y) << ",\n     \"matrix_world\": " << Rows(b.matrix_world)
       << "},\n";
  }
  py << "]\n\n";
  return py.str();
}

}  // namespace

BlenderCamera ToBlenderCamera(const Camera& c, const Eigen::Matrix3d& blender_from_world) {
  BlenderCamera b;
  b.width = c.width;
  b.height = c.height;
  // Non-square pixels: the wider pixel side gets the aspect (fx > fy: pixels taller than wide).
  if (c.fx > c.fy) b.pixel_aspect_y = c.fx / c.fy;
  if (c.fy > c.fx) b.pixel_aspect_x = c.fy / c.fx;
  const double view_px = c.width;  // the sensor is fitted to the image's width
  b.lens_mm = c.fx * b.sensor_width_mm / view_px;
  // Blender's shift is in units of the fitted side, from the image's centre ((W - 1) / 2 with
  // pixel centres at integers); +x moves the frame right, +y up (the image's v goes down).
  b.shift_x = -(c.cx - (c.width - 1) / 2.0) / view_px;
  b.shift_y = (c.cy - (c.height - 1) / 2.0) / view_px * (b.pixel_aspect_y / b.pixel_aspect_x);
  Eigen::Matrix4d to_blender = Eigen::Matrix4d::Identity();
  to_blender.block<3, 3>(0, 0) = blender_from_world;
  const Eigen::Matrix4d flip = Eigen::Vector4d(1, -1, -1, 1).asDiagonal();  // OpenCV's y down, z forward
  b.matrix_world = to_blender * c.world_from_camera * flip;
  return b;
}

std::vector<std::string> WriteBlenderExport(const ExportScene& s, const fs::path& dir) {
  std::vector<std::string> files = {"scene.py", "mesh.ply"};
  const bool has_world = s.environment.height > 0;
  WritePly(dir / "mesh.ply", s.mesh);
  if (has_world) {
    WriteExr(dir / "world.exr", BlenderWorldImage(s.environment, s.up, s.environment.height));
    files.push_back("world.exr");
  }
  WriteTextAtomically(dir / "scene.py", DataBlock(s, has_world) + kBlenderSceneScript);  // last: it names the others
  return files;
}

}  // namespace lp
