#include "tests/test_util.h"

#include <cmath>

#include "common/error.h"
#include "common/rng.h"

namespace lp::test {

Mesh Plane(double size, double rho) {
  Mesh m;
  const float h = static_cast<float>(size / 2);
  m.positions = {{-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0}};
  m.normals.assign(4, Eigen::Vector3f(0, 0, 1));
  m.albedo.assign(4, Eigen::Vector3f::Constant(static_cast<float>(rho)));
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  return m;
}

Mesh FineFloor(double rho, double max_tilt) {
  Rng rng(11);
  Mesh m;
  const int n = 101;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      m.positions.emplace_back(-0.5f + 0.01f * x, -0.5f + 0.01f * y, 0.f);
      const double a = 2 * M_PI * rng.Uniform(), t = max_tilt * rng.Uniform();
      m.normals.emplace_back(Eigen::Vector3f(static_cast<float>(std::sin(t) * std::cos(a)),
                                             static_cast<float>(std::sin(t) * std::sin(a)), static_cast<float>(std::cos(t))));
      m.albedo.emplace_back(Eigen::Vector3f::Constant(static_cast<float>(rho)));
    }
  for (int y = 0; y + 1 < n; ++y)
    for (int x = 0; x + 1 < n; ++x) {
      const int i = y * n + x;
      m.triangles.emplace_back(i, i + 1, i + n + 1);
      m.triangles.emplace_back(i, i + n + 1, i + n);
    }
  return m;
}

Mesh Square(double cx, double cy, double z, double half, double rho) {
  Mesh m;
  const float x0 = cx - half, x1 = cx + half, y0 = cy - half, y1 = cy + half, zz = z;
  m.positions = {{x0, y0, zz}, {x1, y0, zz}, {x1, y1, zz}, {x0, y1, zz}};
  m.normals.assign(4, Eigen::Vector3f(0, 0, -1));
  m.albedo.assign(4, Eigen::Vector3f::Constant(static_cast<float>(rho)));
  m.triangles = {{0, 2, 1}, {0, 3, 2}};
  return m;
}

Mesh Ball(double radius, double rho, int rings, int segments) {
  return UvSphere(Eigen::Vector3f::Zero(), static_cast<float>(radius), Eigen::Vector3f::Constant(static_cast<float>(rho)),
                  rings, segments);
}

Camera LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, int w, int h, double hfov_deg) {
  return Camera::LookAt(eye, target, Eigen::Vector3d::UnitZ(), w, h, hfov_deg);
}

View BlankView(const Camera& cam) {
  View v;
  v.camera = cam;
  v.image = ImageRGB(cam.width, cam.height);
  v.valid.assign(v.image.pixels(), 1);
  return v;
}

Mesh Merge(Mesh a, const Mesh& b) {
  const int n = static_cast<int>(a.positions.size());
  a.positions.insert(a.positions.end(), b.positions.begin(), b.positions.end());
  a.normals.insert(a.normals.end(), b.normals.begin(), b.normals.end());
  a.albedo.insert(a.albedo.end(), b.albedo.begin(), b.albedo.end());
  for (auto t : b.triangles) a.triangles.push_back({t[0] + n, t[1] + n, t[2] + n});
  return a;
}

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace lp::test
