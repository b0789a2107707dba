#include "calibration/vignetting.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

#include "common/error.h"

namespace lp {

namespace {

double Radius(double x, double y, int w, int h, double cx, double cy) {
  const double half_diag = 0.5 * std::sqrt(static_cast<double>(w) * w + static_cast<double>(h) * h);
  return std::hypot(x - cx, y - cy) / half_diag;
}

/// argmin |A x - b| for A's rows and b.
template <int N>
Eigen::Matrix<double, N, 1> LeastSquares(const std::vector<Eigen::Matrix<double, N, 1>>& rows, const std::vector<double>& rhs) {
  Eigen::MatrixXd A(rows.size(), N);
  Eigen::VectorXd b(rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    A.row(static_cast<Eigen::Index>(i)) = rows[i].transpose();
    b[static_cast<Eigen::Index>(i)] = rhs[i];
  }
  return A.colPivHouseholderQr().solve(b);
}

}  // namespace

double Vignetting::At(double x, double y, int w, int h) const {
  // Past the corners (an off-centre centre) the polynomial is not trusted: V(1) there.
  const double r = std::min(1.0, Radius(x, y, w, h, cx >= 0 ? cx : 0.5 * w - 0.5, cy >= 0 ? cy : 0.5 * h - 0.5));
  const double r2 = r * r;
  return 1 + r2 * (a + r2 * (b + r2 * c));
}

bool Vignetting::Plausible() const {
  if (!std::isfinite(a) || !std::isfinite(b) || !std::isfinite(c)) return false;
  for (int i = 0; i <= 100; ++i) {
    const double r2 = (i / 100.0) * (i / 100.0);
    if (!(1 + r2 * (a + r2 * (b + r2 * c)) > 0.05)) return false;
  }
  return true;
}

Vignetting FitVignettingFlatField(const std::vector<ImageRGB>& images) {
  if (images.empty()) throw InputError("vignetting: no flat-field images");
  const int w = images[0].width, h = images[0].height;
  for (const ImageRGB& im : images)
    if (im.width != w || im.height != h) throw InputError("vignetting: the flat-field images differ in size");
  // I = k (1 + a r^2 + b r^4 + c r^6) = k + (ka) r^2 + (kb) r^4 + (kc) r^6: linear in
  // (k, ka, kb, kc); rows on a grid of at most ~20,000 pixels.
  const int step = std::max(1, static_cast<int>(std::sqrt(static_cast<double>(w) * h / 20000.0)));
  std::vector<Eigen::Vector4d> rows;
  std::vector<double> rhs;
  for (int y = 0; y < h; y += step)
    for (int x = 0; x < w; x += step) {
      double sum = 0;
      int n = 0;
      for (const ImageRGB& im : images)
        for (int ch = 0; ch < 3; ++ch) {
          const float v = im.at(x, y)[ch];
          if (std::isfinite(v) && v > 0) {
            sum += v;
            ++n;
          }
        }
      if (n == 0) continue;
      const double r2 = std::pow(Radius(x, y, w, h, 0.5 * w - 0.5, 0.5 * h - 0.5), 2);
      rows.emplace_back(1, r2, r2 * r2, r2 * r2 * r2);
      rhs.push_back(sum / n);
    }
  if (rows.size() < 10) throw InputError("vignetting: too few usable pixels in the flat-field images");
  const Eigen::Vector4d x = LeastSquares(rows, rhs);
  if (!(x[0] > 0)) throw InputError("vignetting: the flat-field images are not usable (no positive level)");
  Vignetting v;
  v.a = x[1] / x[0];
  v.b = x[2] / x[0];
  v.c = x[3] / x[0];
  if (!v.Plausible()) throw InputError("vignetting: the fit falls to zero inside the image (not a flat field?)");
  return v;
}

Vignetting FitVignettingPairs(const std::vector<VignettingPair>& pairs) {
  // In logarithms the unknowns are on one side and the noise on the other (no
  // errors-in-variables bias): log v_i - log v_j = L(r_i) - L(r_j), with
  // L(r) = log V(r) = al r^2 + be r^4 + ga r^6 (L(0) = 0). Then V = exp(L) is projected
  // onto 1 + a r^2 + b r^4 + c r^6 over r in [0, 1].
  std::vector<Eigen::Vector3d> rows;
  std::vector<double> rhs;
  double spread = 0;
  for (const VignettingPair& p : pairs) {
    if (!(p.value_i > 0 && p.value_j > 0) || !std::isfinite(p.value_i) || !std::isfinite(p.value_j)) continue;
    const double i2 = p.r_i * p.r_i, j2 = p.r_j * p.r_j;
    rows.emplace_back(i2 - j2, i2 * i2 - j2 * j2, i2 * i2 * i2 - j2 * j2 * j2);
    rhs.push_back(std::log(p.value_i) - std::log(p.value_j));
    spread = std::max(spread, std::abs(i2 - j2));
  }
  if (rows.size() < 20) throw InputError("vignetting: too few surface points seen twice (" + std::to_string(rows.size()) + ")");
  if (spread < 0.1) throw InputError("vignetting: the points are seen at nearly the same radius; V cannot be told apart");
  const Eigen::Vector3d L = LeastSquares(rows, rhs);
  Eigen::MatrixXd P(101, 3);
  Eigen::VectorXd q(101);
  for (int k = 0; k <= 100; ++k) {
    const double r2 = (k / 100.0) * (k / 100.0);
    P.row(k) << r2, r2 * r2, r2 * r2 * r2;
    q[k] = std::exp(L[0] * r2 + L[1] * r2 * r2 + L[2] * r2 * r2 * r2) - 1;
  }
  const Eigen::Vector3d x = P.colPivHouseholderQr().solve(q);
  Vignetting v;
  v.a = x[0];
  v.b = x[1];
  v.c = x[2];
  if (!v.Plausible()) throw InputError("vignetting: the fit falls to zero inside the image (too few or noisy points)");
  return v;
}

}  // namespace lp
