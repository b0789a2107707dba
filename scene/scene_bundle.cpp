#include "scene/scene_bundle.h"

#include <algorithm>
#include <cmath>

#include <Eigen/LU>
#include <nlohmann/json.hpp>

#include "common/atomic_file.h"
#include "common/color.h"
#include "common/error.h"
#include "common/image_io.h"

namespace lp {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

double Number(const json& j, const char* key, const std::string& name, const std::string& where) {
  if (!j.contains(key)) throw InputError(name, where + " lacks \"" + key + "\"");
  if (!j[key].is_number()) throw InputError(name, where + " \"" + key + "\" is not a number");
  const double v = j[key].get<double>();
  if (!std::isfinite(v)) throw InputError(name, where + " \"" + key + "\" is not finite");
  return v;
}

}  // namespace

SceneBundle ParseSceneJson(const std::string& text, const std::string& name) {
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    throw InputError(name, std::string("malformed JSON: ") + e.what());
  }
  if (!j.is_object()) throw InputError(name, "top level must be an object");
  SceneBundle b;
  if (j.contains("mesh")) {
    if (!j["mesh"].is_string()) throw InputError(name, "\"mesh\" must be a string");
    b.mesh_file = j["mesh"].get<std::string>();
  }
  if (j.contains("up")) {
    const json& u = j["up"];
    if (!u.is_array() || u.size() != 3) throw InputError(name, "\"up\" must be an array of 3 numbers");
    for (int c = 0; c < 3; ++c) {
      if (!u[c].is_number()) throw InputError(name, "\"up\" must be an array of 3 numbers");
      b.up[c] = u[c].get<double>();
    }
    if (!b.up.allFinite() || b.up.norm() < 1e-12) throw InputError(name, "\"up\" must be a finite non-zero vector");
    b.up.normalize();
  }
  if (!j.contains("views") || !j["views"].is_array() || j["views"].empty())
    throw InputError(name, "\"views\" must be a non-empty array");
  int k = 0;
  for (const json& v : j["views"]) {
    const std::string where = "view " + std::to_string(k++);
    if (!v.is_object()) throw InputError(name, where + " must be an object");
    View view;
    if (!v.contains("image") || !v["image"].is_string()) throw InputError(name, where + " lacks \"image\"");
    view.image_file = v["image"].get<std::string>();
    if (v.contains("saturation")) {
      if (!v["saturation"].is_number() || !(v["saturation"].get<double>() > 0) ||
          !std::isfinite(v["saturation"].get<double>()))
        throw InputError(name, where + " \"saturation\" must be a positive number");
      view.saturation = v["saturation"].get<double>();
    }
    // The optional files beside the image: "" where not named.
    for (const auto& [key, file] : {std::pair<const char*, std::string*>{"mask", &view.mask_file},
                                    {"clipped", &view.clipped_file},
                                    {"clipped_off", &view.clipped_off_file}}) {
      if (!v.contains(key)) continue;
      if (!v[key].is_string()) throw InputError(name, where + " \"" + key + "\" must be a string");
      *file = v[key].get<std::string>();
    }
    Camera& c = view.camera;
    const double w = Number(v, "width", name, where), h = Number(v, "height", name, where);
    if (w < 1 || h < 1 || w > 16384 || h > 16384 || w != std::floor(w) || h != std::floor(h))
      throw InputError(name, where + " has invalid width/height");
    c.width = static_cast<int>(w);
    c.height = static_cast<int>(h);
    c.fx = Number(v, "fx", name, where);
    c.fy = Number(v, "fy", name, where);
    c.cx = Number(v, "cx", name, where);
    c.cy = Number(v, "cy", name, where);
    if (c.fx <= 0 || c.fy <= 0) throw InputError(name, where + " focal lengths must be positive");
    if (!v.contains("world_from_camera") || !v["world_from_camera"].is_array() || v["world_from_camera"].size() != 4)
      throw InputError(name, where + " \"world_from_camera\" must be a 4x4 array of rows");
    for (int r = 0; r < 4; ++r) {
      const json& row = v["world_from_camera"][r];
      if (!row.is_array() || row.size() != 4)
        throw InputError(name, where + " \"world_from_camera\" must be a 4x4 array of rows");
      for (int col = 0; col < 4; ++col) {
        if (!row[col].is_number()) throw InputError(name, where + " \"world_from_camera\" has a non-number");
        c.world_from_camera(r, col) = row[col].get<double>();
      }
    }
    if (!c.world_from_camera.allFinite()) throw InputError(name, where + " \"world_from_camera\" is not finite");
    const Eigen::Matrix3d R = c.world_from_camera.block<3, 3>(0, 0);
    if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-3 || R.determinant() < 0)
      throw InputError(name, where + " \"world_from_camera\" rotation is not a proper rotation");
    b.views.push_back(std::move(view));
  }
  return b;
}

void MarkUnusablePixels(View* view) {
  View& v = *view;
  if (v.valid.size() != v.image.pixels()) v.valid.assign(v.image.pixels(), 1);
  for (std::size_t i = 0; i < v.image.pixels(); ++i) {
    if (!v.valid[i]) continue;
    const float* p = &v.image.data[3 * i];
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
      v.valid[i] = 0;
      ++v.non_finite;
    } else if (p[0] < 0 || p[1] < 0 || p[2] < 0) {
      v.valid[i] = 0;
      ++v.negative;
    } else if (p[0] >= v.saturation || p[1] >= v.saturation || p[2] >= v.saturation) {
      v.valid[i] = 0;
      ++v.saturated;
      if (v.clipped.size() != v.image.pixels()) v.clipped.assign(v.image.pixels(), 0);
      v.clipped[i] = 1;
    }
  }
}

namespace {

/// Reads a view's mask of clipped pixels named `file` (none when empty) into `flags`: 1
/// where it is non-zero, and those pixels are not valid.
void ReadClippedMask(const fs::path& dir, const std::string& file, const std::string& what, View* v,
                     std::vector<std::uint8_t>* flags) {
  if (file.empty()) return;
  const fs::path cp = dir / file;
  Mask m = ReadMask(cp);
  if (m.width != v->image.width || m.height != v->image.height)
    throw InputError(cp.string(), what + " mask size does not match the image");
  flags->assign(m.data.size(), 0);
  for (std::size_t i = 0; i < m.data.size(); ++i)
    if (m.data[i]) (*flags)[i] = 1, v->valid[i] = 0;
}

}  // namespace

SceneBundle LoadSceneBundle(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw InputError(dir.string(), "scene directory not found");
  const fs::path json_path = dir / "scene.json";
  SceneBundle b = ParseSceneJson(ReadTextFile(json_path), json_path.string());
  b.dir = dir;
  const fs::path mesh_path = dir / b.mesh_file;
  b.mesh = ReadPly(mesh_path);
  b.degenerate_triangles_removed = SanitizeMesh(&b.mesh, mesh_path.string());
  for (View& v : b.views) {
    const fs::path ip = dir / v.image_file;
    ImageEncoding encoding = ImageEncoding::kLinearFloat;
    v.image = ReadImageLinear(ip, &encoding);
    // An integer image is clipped at its top code unless scene.json says otherwise.
    if (!std::isfinite(v.saturation) && encoding != ImageEncoding::kLinearFloat) v.saturation = 1.0;
    if (v.image.width != v.camera.width || v.image.height != v.camera.height)
      throw InputError(ip.string(), "image is " + std::to_string(v.image.width) + "x" +
                                        std::to_string(v.image.height) + " but scene.json says " +
                                        std::to_string(v.camera.width) + "x" + std::to_string(v.camera.height));
    v.valid.assign(v.image.pixels(), 1);
    if (!v.mask_file.empty()) {
      const fs::path mp = dir / v.mask_file;
      Mask m = ReadMask(mp);
      if (m.width != v.image.width || m.height != v.image.height)
        throw InputError(mp.string(), "mask size does not match the image");
      for (std::size_t i = 0; i < m.data.size(); ++i)
        if (!m.data[i]) { v.valid[i] = 0; ++v.masked_out; }
    }
    ReadClippedMask(dir, v.clipped_file, "clipped", &v, &v.clipped);
    ReadClippedMask(dir, v.clipped_off_file, "clipped_off", &v, &v.clipped_off);
    MarkUnusablePixels(&v);
  }
  const fs::path truth = dir / "truth.json";
  if (fs::exists(truth, ec)) b.truth_json = ReadTextFile(truth);
  return b;
}

void WriteSceneBundle(const fs::path& dir, const SceneBundle& bundle) {
  const fs::path parent = dir.parent_path().empty() ? fs::path(".") : dir.parent_path();
  std::error_code ec;
  fs::create_directories(parent, ec);
  const fs::path tmp = parent / (".tmp." + dir.filename().string());
  fs::remove_all(tmp, ec);
  fs::create_directories(tmp, ec);
  if (ec) throw InputError(tmp.string(), "cannot create directory: " + ec.message());
  try {
    json j;
    j["mesh"] = "mesh.ply";
    j["up"] = {bundle.up.x(), bundle.up.y(), bundle.up.z()};
    j["views"] = json::array();
    for (std::size_t k = 0; k < bundle.views.size(); ++k) {
      const View& v = bundle.views[k];
      const Camera& c = v.camera;
      json jv;
      jv["image"] = "view" + std::to_string(k) + ".exr";
      WriteExr(tmp / jv["image"].get<std::string>(), v.image);
      if (!v.valid.empty()) {
        jv["mask"] = "mask" + std::to_string(k) + ".png";
        Mask m{c.width, c.height, {}};
        m.data.resize(v.valid.size());
        for (std::size_t i = 0; i < v.valid.size(); ++i) m.data[i] = v.valid[i] ? 255 : 0;
        WriteMask(tmp / jv["mask"].get<std::string>(), m);
      }
      for (const auto& [key, flags] : {std::pair<std::string, const std::vector<std::uint8_t>*>{"clipped", &v.clipped},
                                       {"clipped_off", &v.clipped_off}}) {
        if (std::find(flags->begin(), flags->end(), 1) == flags->end()) continue;
        jv[key] = key + std::to_string(k) + ".png";
        Mask m{c.width, c.height, {}};
        m.data.resize(flags->size());
        for (std::size_t i = 0; i < flags->size(); ++i) m.data[i] = (*flags)[i] ? 255 : 0;
        WriteMask(tmp / jv[key].get<std::string>(), m);
      }
      if (std::isfinite(v.saturation)) jv["saturation"] = v.saturation;
      jv["width"] = c.width;
      jv["height"] = c.height;
      jv["fx"] = c.fx; jv["fy"] = c.fy; jv["cx"] = c.cx; jv["cy"] = c.cy;
      json rows = json::array();
      for (int r = 0; r < 4; ++r)
        rows.push_back({c.world_from_camera(r, 0), c.world_from_camera(r, 1), c.world_from_camera(r, 2),
                        c.world_from_camera(r, 3)});
      jv["world_from_camera"] = rows;
      j["views"].push_back(jv);
    }
    WritePly(tmp / "mesh.ply", bundle.mesh);
    if (bundle.truth_json) WriteTextAtomically(tmp / "truth.json", *bundle.truth_json);
    for (const auto& [name, text] : bundle.extra_files) {
      LP_CHECK(!name.empty() && fs::path(name).filename() == name && name != "scene.json" && name != "mesh.ply",
               "extra bundle file must be a plain file name not used by the bundle");
      WriteTextAtomically(tmp / name, text);
    }
    WriteTextAtomically(tmp / "scene.json", j.dump(2) + "\n");
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
  // Swap into place: the old bundle (if any) is removed only after the new one is complete.
  const fs::path old = parent / (".old." + dir.filename().string());
  fs::remove_all(old, ec);
  const bool replacing = fs::exists(dir);
  if (replacing) {
    fs::rename(dir, old, ec);
    if (ec) {
      fs::remove_all(tmp, ec);
      throw InputError(dir.string(), "cannot replace the existing bundle: " + ec.message());
    }
  }
  fs::rename(tmp, dir, ec);
  if (ec) {
    const std::string why = ec.message();
    if (replacing) fs::rename(old, dir, ec);  // put the old bundle back
    fs::remove_all(tmp, ec);
    throw InputError(dir.string(), "cannot move the bundle into place: " + why);
  }
  fs::remove_all(old, ec);
}

}  // namespace lp
