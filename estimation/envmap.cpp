#include "estimation/envmap.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

#include "common/error.h"

namespace lp {
namespace {
constexpr double kPi = 3.14159265358979323846;
}

EnvMap::EnvMap(int rings, const Eigen::Vector3d& up) : rings_(rings) {
  LP_CHECK(rings >= 2, "need at least 2 rings, got " << rings);
  LP_CHECK(up.allFinite() && up.norm() > 0, "bad up vector");
  up_ = up.normalized();
  // Any vector not parallel to up gives the azimuth origin.
  const Eigen::Vector3d helper = std::abs(up_.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  ex_ = (helper - helper.dot(up_) * up_).normalized();
  ey_ = up_.cross(ex_);

  const double dtheta = kPi / (rings - 1);
  for (int i = 0; i < rings; ++i) {
    const double theta = i * dtheta;
    const double circumference = 2 * kPi * std::sin(theta) / dtheta;
    const int n = std::max(1, static_cast<int>(std::ceil(circumference - 1e-9)));
    ring_start_.push_back(static_cast<int>(dirs_.size()));
    ring_count_.push_back(n);
    const double lo = i == 0 ? 0.0 : theta - dtheta / 2;
    const double hi = i == rings - 1 ? kPi : theta + dtheta / 2;
    ring_theta_lo_.push_back(lo);
    ring_theta_hi_.push_back(hi);
    const double band = std::cos(lo) - std::cos(hi);
    for (int k = 0; k < n; ++k) {
      const double phi = 2 * kPi * (k + 0.5) / n;
      dirs_.push_back(FromSpherical(theta, phi));
      omega_.push_back(2 * kPi * band / n);
      ring_of_.push_back(i);
    }
  }
}

std::vector<EnvMap::Neighbours> EnvMap::Adjacency() const {
  const double dtheta = kPi / (rings_ - 1);
  std::vector<Neighbours> out;
  for (int i = 0; i < rings_; ++i) {
    const int n = ring_count_[i], s = ring_start_[i];
    // Along the ring: the sectors' radial edges (the band's polar extent) over the arc between centres.
    const double arc = std::sin(i * dtheta) * 2 * kPi / n;
    if (n == 2) out.push_back({s, s + 1, 2 * (ring_theta_hi_[i] - ring_theta_lo_[i]) / arc});
    if (n > 2)
      for (int k = 0; k < n; ++k) {
        const int a = s + k, b = s + (k + 1) % n;
        out.push_back({std::min(a, b), std::max(a, b), (ring_theta_hi_[i] - ring_theta_lo_[i]) / arc});
      }
    if (i + 1 == rings_) continue;
    // To the next ring: the sectors' overlap in azimuth along the band edge between them,
    // over the polar distance between the rings.
    const int m = ring_count_[i + 1], t = ring_start_[i + 1];
    const double edge = std::sin(ring_theta_hi_[i]);
    for (int k = 0; k < n; ++k)
      for (int q = 0; q < m; ++q) {
        const double lo = std::max(2 * kPi * k / n, 2 * kPi * q / m), hi = std::min(2 * kPi * (k + 1) / n, 2 * kPi * (q + 1) / m);
        if (hi - lo > 1e-12) out.push_back({s + k, t + q, edge * (hi - lo) / dtheta});
      }
  }
  return out;
}

void EnvMap::ToSpherical(const Eigen::Vector3d& w, double* theta, double* phi) const {
  const double z = w.dot(up_), x = w.dot(ex_), y = w.dot(ey_);
  *theta = std::atan2(std::sqrt(x * x + y * y), z);
  double p = std::atan2(y, x);
  if (p < 0) p += 2 * kPi;
  if (!(p < 2 * kPi)) p = 0;  // also catches NaN
  *phi = p;
}

Eigen::Vector3d EnvMap::FromSpherical(double theta, double phi) const {
  const double s = std::sin(theta);
  return s * std::cos(phi) * ex_ + s * std::sin(phi) * ey_ + std::cos(theta) * up_;
}

int EnvMap::Lookup(const Eigen::Vector3d& w) const {
  double theta, phi;
  ToSpherical(w, &theta, &phi);
  if (!std::isfinite(theta)) theta = 0;
  const double dtheta = kPi / (rings_ - 1);
  const int i = std::clamp(static_cast<int>(std::floor(theta / dtheta + 0.5)), 0, rings_ - 1);
  const int n = ring_count_[i];
  const int k = std::clamp(static_cast<int>(phi / (2 * kPi) * n), 0, n - 1);
  return ring_start_[i] + k;
}

Eigen::Vector3d EnvMap::SampleInCell(int j, double u1, double u2) const {
  const int i = ring_of_[j];
  const int k = j - ring_start_[i];
  const double zlo = std::cos(ring_theta_hi_[i]), zhi = std::cos(ring_theta_lo_[i]);
  const double z = std::clamp(zlo + u1 * (zhi - zlo), -1.0, 1.0);
  const double phi = 2 * kPi * (k + u2) / ring_count_[i];
  const double s = std::sqrt(std::max(0.0, 1 - z * z));
  return s * std::cos(phi) * ex_ + s * std::sin(phi) * ey_ + z * up_;
}

ImageRGB EnvMap::ToEquirect(const std::vector<double>& rgb, int height) const {
  LP_CHECK(rgb.size() == 3 * dirs_.size(), "rgb size " << rgb.size());
  ImageRGB img(2 * height, height);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < 2 * height; ++x) {
      const double theta = (y + 0.5) / height * kPi;
      const double phi = (x + 0.5) / (2 * height) * 2 * kPi;
      const int j = Lookup(FromSpherical(theta, phi));
      for (int c = 0; c < 3; ++c) img.at(x, y)[c] = static_cast<float>(rgb[3 * j + c]);
    }
  return img;
}

Eigen::Vector3d SampleEquirect(const ImageRGB& e, double theta, double phi) {
  const double fx = phi / (2 * kPi) * e.width - 0.5;
  const double fy = theta / kPi * e.height - 0.5;
  const int x0 = static_cast<int>(std::floor(fx)), y0 = static_cast<int>(std::floor(fy));
  const double ax = fx - x0, ay = fy - y0;
  Eigen::Vector3d out = Eigen::Vector3d::Zero();
  for (int dy = 0; dy < 2; ++dy)
    for (int dx = 0; dx < 2; ++dx) {
      const int x = ((x0 + dx) % e.width + e.width) % e.width;
      const int y = std::clamp(y0 + dy, 0, e.height - 1);
      const double w = (dx ? ax : 1 - ax) * (dy ? ay : 1 - ay);
      const float* p = e.at(x, y);
      out += w * Eigen::Vector3d(p[0], p[1], p[2]);
    }
  return out;
}

std::vector<double> EnvMap::FromEquirect(const ImageRGB& equirect, int samples_per_cell) const {
  LP_CHECK(equirect.width > 0 && equirect.height > 0, "empty map");
  const int s = std::max(1, static_cast<int>(std::sqrt(static_cast<double>(samples_per_cell))));
  std::vector<double> out(3 * dirs_.size(), 0.0);
  for (int j = 0; j < size(); ++j) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int a = 0; a < s; ++a)
      for (int b = 0; b < s; ++b) {
        double theta, phi;
        ToSpherical(SampleInCell(j, (a + 0.5) / s, (b + 0.5) / s), &theta, &phi);
        sum += SampleEquirect(equirect, theta, phi);
      }
    for (int c = 0; c < 3; ++c) out[3 * j + c] = sum[c] / (s * s);
  }
  return out;
}

}  // namespace lp
