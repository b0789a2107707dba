#include "reconstruction/icp.h"

#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "common/parallel.h"

namespace lp {

namespace {

constexpr double kPi = 3.14159265358979323846;

/// 6x6 normal equations (upper triangle used) plus the right side and residual sums.
struct Normal {
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
  double sq = 0;
  long inliers = 0, valid = 0, overlap = 0;
  void Add(const Normal& o) {
    A += o.A;
    b += o.b;
    sq += o.sq;
    inliers += o.inliers;
    overlap += o.overlap;
    valid += o.valid;
  }
};

/// One Gauss-Newton system at one level for the current pose.
Normal Accumulate(const DepthLevel& f, const ModelMaps& model, int level, const Eigen::Matrix4f& pose,
                  const IcpOptions& o) {
  const Camera& mk = model.k[level];
  const auto& mv = model.vertex[level];
  const auto& mn = model.normal[level];
  const Eigen::Matrix4f model_from_world = model.world_from_camera.inverse().cast<float>();
  const Eigen::Matrix3f R = pose.block<3, 3>(0, 0), Rm = model_from_world.block<3, 3>(0, 0);
  const Eigen::Vector3f t = pose.block<3, 1>(0, 3), tm = model_from_world.block<3, 1>(0, 3);
  const float cos_max = static_cast<float>(std::cos(o.max_angle_deg * kPi / 180));
  const float fx = static_cast<float>(mk.fx), fy = static_cast<float>(mk.fy), cx = static_cast<float>(mk.cx),
              cy = static_cast<float>(mk.cy);
  const int h = f.k.height, w = f.k.width;
  constexpr std::size_t kRows = 8;
  const std::size_t chunks = (static_cast<std::size_t>(h) + kRows - 1) / kRows;
  std::vector<Normal> partial(chunks);
  ParallelForChunks(0, chunks, 1, [&](std::size_t c0, std::size_t c1) {
    for (std::size_t c = c0; c < c1; ++c) {
      Normal& nq = partial[c];
      Eigen::Matrix<float, 6, 6> A = Eigen::Matrix<float, 6, 6>::Zero();
      Eigen::Matrix<float, 6, 1> b = Eigen::Matrix<float, 6, 1>::Zero();
      for (int y = static_cast<int>(c * kRows); y < std::min(h, static_cast<int>((c + 1) * kRows)); ++y)
        for (int x = 0; x < w; ++x) {
          const std::size_t p = static_cast<std::size_t>(y) * w + x;
          if (!f.valid(p)) continue;
          ++nq.valid;
          const Eigen::Vector3f s = R * f.vertex[p] + t;  // world
          const Eigen::Vector3f sm = Rm * s + tm;         // model camera
          if (sm.z() <= 0) continue;
          const float uf = fx * sm.x() / sm.z() + cx + 0.5f, vf = fy * sm.y() / sm.z() + cy + 0.5f;
          if (uf < 0 || vf < 0 || uf >= mk.width || vf >= mk.height) continue;
          const std::size_t q = static_cast<std::size_t>(static_cast<int>(vf)) * mk.width + static_cast<int>(uf);
          const Eigen::Vector3f& d = mv[q];
          const Eigen::Vector3f& n = mn[q];
          if (!(d.x() == d.x()) || !(n.x() == n.x())) continue;
          ++nq.overlap;
          if ((s - d).squaredNorm() > o.max_distance * o.max_distance) continue;
          if (n.dot(R * f.normal[p]) < cos_max) continue;
          const float r = n.dot(s - d);
          // J = [s x n, n] (written out: Eigen's vectorized 3-vector cross trips GCC's bounds check).
          Eigen::Matrix<float, 6, 1> J;
          J << s.y() * n.z() - s.z() * n.y(), s.z() * n.x() - s.x() * n.z(), s.x() * n.y() - s.y() * n.x(), n;
          for (int i = 0; i < 6; ++i) {  // upper triangle of J J^T
            for (int j = i; j < 6; ++j) A(i, j) += J[i] * J[j];
            b[i] += J[i] * r;
          }
          nq.sq += static_cast<double>(r) * r;
          ++nq.inliers;
        }
      nq.A = A.cast<double>();
      nq.b = b.cast<double>();
    }
  });
  Normal total;
  for (const Normal& n : partial) total.Add(n);  // fixed order: independent of threads
  total.A = total.A.selfadjointView<Eigen::Upper>();
  return total;
}

Eigen::Matrix4d Exp(const Eigen::Matrix<double, 6, 1>& xi) {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  const Eigen::Vector3d w = xi.head<3>();
  const double angle = w.norm();
  if (angle > 0) T.block<3, 3>(0, 0) = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
  T.block<3, 1>(0, 3) = xi.tail<3>();
  return T;
}

}  // namespace

double PoseDistance(const Eigen::Matrix4d& a, const Eigen::Matrix4d& b) {
  const Eigen::Matrix4d d = a.inverse() * b;
  return d.block<3, 1>(0, 3).norm() + 0.5 * RotationAngle(d);
}

double RotationAngle(const Eigen::Matrix4d& t) {
  return std::acos(std::clamp((t.block<3, 3>(0, 0).trace() - 1) / 2, -1.0, 1.0));
}

ModelMaps MakeModelMaps(const Camera& k, const std::vector<Eigen::Vector3f>& vertex,
                        const std::vector<Eigen::Vector3f>& normal, const Eigen::Matrix4d& world_from_camera,
                        int levels, int first_level) {
  ModelMaps m;
  m.world_from_camera = world_from_camera;
  m.k.push_back(k);
  m.vertex.push_back(vertex);
  m.normal.push_back(normal);
  for (int l = 1; l < levels; ++l) {
    if (l <= first_level) {  // the raycast is already this coarse
      m.k.push_back(m.k.back());
      m.vertex.push_back(m.vertex.back());
      m.normal.push_back(m.normal.back());
      continue;
    }
    const Camera& fk = m.k.back();
    // Every second pixel (not 2x2 means: a vertex map does not average): pixel x here is
    // pixel 2x there.
    Camera ck = fk;
    ck.width /= 2;
    ck.height /= 2;
    ck.fx *= 0.5;
    ck.fy *= 0.5;
    ck.cx *= 0.5;
    ck.cy *= 0.5;
    std::vector<Eigen::Vector3f> v(static_cast<std::size_t>(ck.width) * ck.height), n(v.size());
    for (int y = 0; y < ck.height; ++y)
      for (int x = 0; x < ck.width; ++x) {
        const std::size_t src = static_cast<std::size_t>(2 * y) * fk.width + 2 * x;
        v[static_cast<std::size_t>(y) * ck.width + x] = m.vertex.back()[src];
        n[static_cast<std::size_t>(y) * ck.width + x] = m.normal.back()[src];
      }
    m.k.push_back(ck);
    m.vertex.push_back(std::move(v));
    m.normal.push_back(std::move(n));
  }
  return m;
}

TrackResult TrackFrameToModel(const std::vector<DepthLevel>& frame, const ModelMaps& model,
                              const Eigen::Matrix4d& initial, const IcpOptions& o) {
  TrackResult res;
  Eigen::Matrix4d pose = initial;
  const int levels = static_cast<int>(std::min({frame.size(), model.k.size(), o.iterations.size()}));
  Normal last;
  int finest = 0;  // the finest level with maps
  while (finest + 1 < levels && !frame[static_cast<std::size_t>(finest)].has_maps()) ++finest;
  for (int level = levels - 1; level >= finest; --level) {
    for (int it = 0; it < o.iterations[static_cast<std::size_t>(level)]; ++it) {
      IcpOptions lo = o;
      if (level == finest) lo.max_distance = std::min(o.max_distance, o.fine_max_distance);
      last = Accumulate(frame[static_cast<std::size_t>(level)], model, level, pose.cast<float>(), lo);
      ++res.iterations;
      if (last.inliers < 6) {
        res.reason = "no overlap with the model";
        return res;
      }
      // A view of one plane (a wall, a floor) leaves directions unconstrained: its system
      // is (nearly) singular, and LDLT would divide by noise.
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(last.A, Eigen::EigenvaluesOnly);
      if (!(eig.eigenvalues()[0] > 1e-6 * eig.eigenvalues()[5])) {
        res.reason = "degenerate geometry (too few surface orientations to fix the pose)";
        return res;
      }
      const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(last.A);
      const Eigen::Matrix<double, 6, 1> xi = ldlt.solve(-last.b);
      if (ldlt.info() != Eigen::Success || !xi.allFinite()) {
        res.reason = "degenerate geometry (ICP system singular)";
        return res;
      }
      pose = Exp(xi) * pose;
      if (xi.norm() < 1e-5) break;  // converged: under 0.01 mm / 0.0006 degrees
    }
  }
  res.world_from_camera = pose;
  res.overlap = last.valid > 0 ? static_cast<double>(last.overlap) / last.valid : 0;
  res.inlier_ratio = last.overlap > 0 ? static_cast<double>(last.inliers) / last.overlap : 0;
  res.rmse = last.inliers > 0 ? std::sqrt(last.sq / last.inliers) : 0;
  const Eigen::Matrix4d step = initial.inverse() * pose;
  const double rot_deg = RotationAngle(step) * 180 / kPi;
  if (res.overlap < o.min_overlap) res.reason = "the frame hardly overlaps the model";
  else if (res.inlier_ratio < o.min_inlier_ratio) res.reason = "too few points match the model";
  else if (res.rmse > o.max_rmse) res.reason = "the frame does not fit the model (large residual)";
  else if (step.block<3, 1>(0, 3).norm() > o.max_step_translation || rot_deg > o.max_step_rotation_deg)
    res.reason = "implausible jump between frames";
  else res.ok = true;
  return res;
}

}  // namespace lp
