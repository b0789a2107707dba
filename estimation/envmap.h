#pragma once
/// The unknowns: an environment map of discrete directions on R rings around `up`
/// (paper, "Environment Light"). Ring i (i = 0..R-1) lies at polar angle
/// theta_i = i*pi/(R-1) from `up`; it holds n_i = max(1, ceil(2*pi*sin(theta_i)/dtheta))
/// points (dtheta = pi/(R-1)), i.e. spaced as close to the inter-ring spacing as
/// possible without exceeding it. 21 rings give 522 directions.
///
/// Cell C_j of direction j is its ring's band (polar angles half-way to the
/// neighbouring rings) times its azimuth sector (half-way to the neighbouring
/// points): the nearest direction in polar angle, then in azimuth. This makes
/// lookup O(1), solid angles exact, and sampling inside a cell trivial.
#include <vector>

#include <Eigen/Core>

#include "common/image.h"

namespace lp {

class EnvMap {
 public:
  /// `rings` >= 2; `up` non-zero (normalized here).
  EnvMap(int rings, const Eigen::Vector3d& up);

  int rings() const { return rings_; }
  int size() const { return static_cast<int>(dirs_.size()); }
  const Eigen::Vector3d& up() const { return up_; }
  /// Unit world direction of cell j.
  const Eigen::Vector3d& direction(int j) const { return dirs_[j]; }
  /// Solid angle of cell j (steradians); the sum over all cells is 4*pi.
  double solid_angle(int j) const { return omega_[j]; }
  int ring_of(int j) const { return ring_of_[j]; }
  int ring_size(int i) const { return ring_count_[i]; }

  /// Cell containing the (not necessarily unit) world direction `w`. O(1).
  int Lookup(const Eigen::Vector3d& w) const;
  /// A direction uniformly distributed (by solid angle) inside cell j, from two uniforms.
  Eigen::Vector3d SampleInCell(int j, double u1, double u2) const;

  /// Polar angle from `up` and azimuth (radians, [0, 2pi)) of world direction `w`.
  void ToSpherical(const Eigen::Vector3d& w, double* theta, double* phi) const;
  Eigen::Vector3d FromSpherical(double theta, double phi) const;

  /// Two cells that share a boundary, and the weight of their difference in a discrete
  /// Dirichlet energy of the map (the boundary's length over the distance between their
  /// centres, both on the unit sphere): sum over the pairs of weight * (f_a - f_b)^2
  /// approximates the integral of |grad f|^2 over the sphere at any ring count.
  struct Neighbours {
    int a = 0, b = 0;
    double weight = 0;
  };
  /// Every pair of cells that share a boundary (a < b), once.
  std::vector<Neighbours> Adjacency() const;

  /// Equirectangular picture of per-cell RGB radiance (`rgb` has 3*size() values):
  /// width = 2*height; pixel row y covers polar angle theta = (y+0.5)/height*pi from
  /// `up` (top row = up), column x covers azimuth phi = (x+0.5)/width*2*pi measured
  /// from the frame's x axis (see frame_x()) towards frame_y() (right-handed around up).
  ImageRGB ToEquirect(const std::vector<double>& rgb, int height) const;

  /// Integrates a continuous equirectangular radiance map given in the same
  /// convention into per-cell mean radiance (3*size() values), with `samples`
  /// stratified samples per cell.
  std::vector<double> FromEquirect(const ImageRGB& equirect, int samples_per_cell = 64) const;

  /// Orthonormal frame: frame_x(), frame_y(), up() (azimuth 0 is along frame_x).
  const Eigen::Vector3d& frame_x() const { return ex_; }
  const Eigen::Vector3d& frame_y() const { return ey_; }

 private:
  int rings_;
  Eigen::Vector3d up_, ex_, ey_;
  std::vector<double> ring_theta_lo_, ring_theta_hi_;  // band edges
  std::vector<int> ring_start_, ring_count_;
  std::vector<Eigen::Vector3d> dirs_;
  std::vector<double> omega_;
  std::vector<int> ring_of_;
};

/// Looks up the radiance of an equirectangular map (EnvMap convention) along a
/// direction given as polar angle / azimuth; bilinear.
Eigen::Vector3d SampleEquirect(const ImageRGB& equirect, double theta, double phi);

}  // namespace lp
