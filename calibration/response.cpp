#include "calibration/response.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include <Eigen/Dense>

#include "common/color.h"
#include "common/error.h"

namespace lp {

double InverseResponse::Apply(int channel, double m) const {
  const std::vector<double>& c = coefficients[static_cast<std::size_t>(channel)];
  double v = 0;
  for (std::size_t n = c.size(); n-- > 0;) v = v * m + c[n];
  return v;
}

InverseResponse InverseResponse::Srgb() {
  // Least squares of degree 8 to sRGB's decoding on 256 values (max error < 0.1 %).
  Eigen::MatrixXd A(256, 9);
  Eigen::VectorXd b(256);
  for (int i = 0; i < 256; ++i) {
    const double m = i / 255.0;
    for (int n = 0; n < 9; ++n) A(i, n) = std::pow(m, n);
    b[i] = SrgbToLinear(static_cast<float>(m));
  }
  const Eigen::VectorXd c = A.colPivHouseholderQr().solve(b);
  InverseResponse r;
  for (auto& ch : r.coefficients) ch.assign(c.data(), c.data() + c.size());
  return r;
}

namespace {

/// One channel: the Mitsunaga-Nayar least squares for degree N with g(1) = 1, given the
/// ratios R_q = e_q / e_{q+1}. Pairs (M_pq, M_p,q+1) are the samples. Returns the
/// coefficients and the RMS of g(M_pq) - R_q g(M_p,q+1).
struct Pair {
  double m0, m1;
  int q, q2;  // images q < q2 (sorted by exposure)
};

/// e_q / e_q2 from the ratios of neighbours.
double RatioOf(const Pair& p, const std::vector<double>& R) {
  double r = 1;
  for (int k = p.q; k < p.q2; ++k) r *= R[static_cast<std::size_t>(k)];
  return r;
}

std::vector<double> SolveDegree(const std::vector<Pair>& pairs, const std::vector<double>& R, int N, double* rms) {
  // g(M) = sum_{n<N} c_n M^n + (1 - sum_{n<N} c_n) M^N
  //  => g(M0) - R g(M1) = sum_n c_n [(M0^n - M0^N) - R (M1^n - M1^N)] + (M0^N - R M1^N)
  Eigen::MatrixXd A(pairs.size(), N);
  Eigen::VectorXd b(pairs.size());
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const Pair& p = pairs[i];
    const double r = RatioOf(p, R);
    const double m0N = std::pow(p.m0, N), m1N = std::pow(p.m1, N);
    for (int n = 0; n < N; ++n) A(i, n) = (std::pow(p.m0, n) - m0N) - r * (std::pow(p.m1, n) - m1N);
    b[i] = -(m0N - r * m1N);
  }
  const Eigen::VectorXd x = A.colPivHouseholderQr().solve(b);
  std::vector<double> c(static_cast<std::size_t>(N) + 1);
  double sum = 0;
  for (int n = 0; n < N; ++n) {
    c[static_cast<std::size_t>(n)] = x[n];
    sum += x[n];
  }
  c[static_cast<std::size_t>(N)] = 1 - sum;
  *rms = std::sqrt((A * x - b).squaredNorm() / std::max<std::size_t>(1, pairs.size()));
  return c;
}

double Eval(const std::vector<double>& c, double m) {
  double v = 0;
  for (std::size_t n = c.size(); n-- > 0;) v = v * m + c[n];
  return v;
}

/// g must rise over [from, 1] (where there are data and above): a fit that turns down is
/// not a response.
bool Monotone(const std::vector<double>& c, double from) {
  double prev = Eval(c, from);
  for (int i = 1; i <= 100; ++i) {
    const double v = Eval(c, from + (1 - from) * i / 100.0);
    if (v < prev - 2e-3) return false;  // a wiggle in a flat dark toe is fine, falling is not
    prev = v;
  }
  return true;
}

}  // namespace

namespace {

/// One Mitsunaga-Nayar update of the exposure ratios `Rn` (sorted order) under the response
/// g of coefficients `c`: R_q = mean over pixels of g(M_pq) / g(M_p,q+1), then scaled as
/// R^k so that the overall exposure range stays the given one (`R`: g -> g^k with R -> R^k
/// fits the images equally well). Returns the largest relative change of a ratio, or
/// nothing (Rn kept) when the ratios g gives are not a response's.
std::optional<double> UpdateRatios(const std::vector<Pair>& pairs, const std::vector<double>& c,
                                   const std::vector<double>& R, std::vector<double>* Rn) {
  const std::size_t Q = R.size() + 1;
  std::vector<double> sum(Q - 1, 0.0);
  std::vector<int> count(Q - 1, 0);
  for (const Pair& p : pairs) {
    if (p.q2 != p.q + 1) continue;  // the ratio of neighbours from their pairs
    const double g1 = Eval(c, p.m1);
    if (g1 <= 1e-6) continue;
    sum[static_cast<std::size_t>(p.q)] += Eval(c, p.m0) / g1;
    ++count[static_cast<std::size_t>(p.q)];
  }
  std::vector<double> next = *Rn;
  bool usable = true;
  for (std::size_t q = 0; q + 1 < Q; ++q)
    if (count[q] > 0) {
      next[q] = sum[q] / count[q];
      usable = usable && std::isfinite(next[q]) && next[q] > 0 && next[q] < 1;
    }
  if (!usable) return std::nullopt;
  double log_given = 0, log_next = 0;
  for (std::size_t q = 0; q + 1 < Q; ++q) {
    log_given += std::log(R[q]);
    log_next += std::log(next[q]);
  }
  const double k = log_next != 0 ? log_given / log_next : 1;
  double change = 0;
  for (std::size_t q = 0; q + 1 < Q; ++q) {
    const double r = std::pow(next[q], k);
    change = std::max(change, std::abs(r / (*Rn)[q] - 1));
    (*Rn)[q] = r;
  }
  return change;
}

/// Throws InputError unless there are two or more images of one size and exposures that
/// are positive and differ by at least 10 %.
void CheckResponseInput(const std::vector<ImageRgb8>& images, const std::vector<double>& exposures) {
  if (images.size() < 2) throw InputError("response: need at least two images of different exposure");
  if (exposures.size() != images.size())
    throw InputError("response: " + std::to_string(images.size()) + " images but " + std::to_string(exposures.size()) +
                     " exposures");
  for (double e : exposures)
    if (!(e > 0) || !std::isfinite(e)) throw InputError("response: exposures must be positive");
  if (*std::max_element(exposures.begin(), exposures.end()) < 1.1 * *std::min_element(exposures.begin(), exposures.end()))
    throw InputError("response: the exposures must differ (at least 10 % between the shortest and the longest)");
  const int w = images[0].width, h = images[0].height;
  for (const ImageRgb8& im : images)
    if (im.width != w || im.height != h || im.data.size() != 3 * im.pixels() || im.pixels() == 0)
      throw InputError("response: the images must all have the same size");
}

}  // namespace

ResponseFit FitResponse(const std::vector<ImageRgb8>& images, const std::vector<double>& exposures,
                        const ResponseFitOptions& o) {
  CheckResponseInput(images, exposures);
  const int w = images[0].width, h = images[0].height;
  // Sort by exposure so that pairs are neighbours in exposure.
  std::vector<std::size_t> order(images.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return exposures[a] < exposures[b]; });
  const std::size_t Q = images.size();
  std::vector<double> R(Q - 1);  // R_q = e_q / e_{q+1} in sorted order
  for (std::size_t q = 0; q + 1 < Q; ++q) R[q] = exposures[order[q]] / exposures[order[q + 1]];

  // Sample positions on a grid spread over the image.
  const std::size_t n = static_cast<std::size_t>(w) * h;
  const std::size_t stride = std::max<std::size_t>(1, n / static_cast<std::size_t>(o.max_samples));
  ResponseFit fit;
  for (int ch = 0; ch < 3; ++ch) {
    std::vector<Pair> pairs;
    // Every pair of exposures where both values are usable (not only neighbours: more
    // constraints on g over the whole range).
    for (std::size_t p = 0; p < n; p += stride)
      for (std::size_t q = 0; q + 1 < Q; ++q)
        for (std::size_t q2 = q + 1; q2 < Q; ++q2) {
          const double m0 = images[order[q]].data[3 * p + ch] / 255.0, m1 = images[order[q2]].data[3 * p + ch] / 255.0;
          if (m0 < o.dark || m0 > o.bright || m1 < o.dark || m1 > o.bright) continue;
          pairs.push_back({m0, m1, static_cast<int>(q), static_cast<int>(q2)});
        }
    if (pairs.size() < 50)
      throw InputError("response: too few usable pixels in channel " + std::to_string(ch) +
                       " (all dark or saturated in neighbouring exposures?)");
    double best_rms = std::numeric_limits<double>::max();
    for (int N = 2; N <= o.max_degree; ++N) {
      std::vector<double> Rn = R, c;
      double rms = 0;
      for (int it = 0; it < (o.refine_ratios ? o.iterations : 1); ++it) {
        c = SolveDegree(pairs, Rn, N, &rms);
        if (!o.refine_ratios) break;
        const std::optional<double> change = UpdateRatios(pairs, c, R, &Rn);
        if (!change || *change < 1e-7) break;  // (none: this degree's g is not a response)
      }
      if (!Monotone(c, o.dark) || !(rms < best_rms * 0.98)) continue;  // a higher degree must earn its place
      best_rms = rms;
      fit.response.coefficients[static_cast<std::size_t>(ch)] = c;
      fit.degree[static_cast<std::size_t>(ch)] = N;
      fit.rms[static_cast<std::size_t>(ch)] = rms;
      if (ch == 1 || fit.exposures.empty()) {  // the ratios from green (the best exposed channel)
        fit.exposures.assign(Q, 1.0);
        std::vector<double> sorted(Q, 1.0);
        for (std::size_t q = 1; q < Q; ++q) sorted[q] = sorted[q - 1] / Rn[q - 1];
        for (std::size_t q = 0; q < Q; ++q) fit.exposures[order[q]] = sorted[q];
      }
    }
    if (fit.response.coefficients[static_cast<std::size_t>(ch)].empty() ||
        !(fit.response.Apply(ch, 0.0) < fit.response.Apply(ch, 1.0)))
      throw InputError("response: no rising response fits channel " + std::to_string(ch));
  }
  // Relative to the first image as given.
  const double e0 = fit.exposures[0];
  for (double& e : fit.exposures) e /= e0;
  return fit;
}

}  // namespace lp
