#pragma once
/// One fit for every kind of light (estimation/lights/light.h): "refine these lights'
/// shapes and intensities on these rows", the rest of the image held. One objective, one
/// Levenberg-Marquardt, one compass search and one intensity refit, whatever the kinds.
#include <cmath>
#include <functional>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "estimation/lights/light.h"
#include "estimation/objective.h"
#include "estimation/robust_loss.h"
#include "estimation/shading_vertices.h"
#include "scene/ray_tracer.h"

namespace lp {

/// A light's unit column on shading vertices (or a sum of scaled columns), 3 per row, and the
/// difference of its two halves (ColumnOut's spread; empty: not known).
struct SplitColumn {
  std::vector<float> value, spread;
};

/// The robust objective of lights on fixed shading vertices, the rest of the image
/// (`base`: the environment's render, 3 per row) held fixed:
///   E = sum rho(y - m . (base + sum_k s_k . c_k(shape_k))) + sum_k alpha log(1 + beta sum_c s_kc),
/// s_k a light's RGB scale (Scale), c_k its unit column (UnitColumn), rho the loss, m 1 or,
/// with `segment` given, per row its surface segment's RGB multiplier: the albedo of each
/// segment (over kMinSegmentRows rows) is then free, eliminated where E is evaluated
/// (variable projection, SegmentMultipliers), so the lights are fitted to the shading
/// within the segments and not to their albedos (docs/method.md, "Albedo left free").
/// `debiased`: the columns are Monte Carlo sums, and their noise adds about
/// rho''(r) Var(m sum_k s_k c_k) / 2 to each term's expectation, more where a light's paths
/// are noisier (a lamp farther along its ray): that is subtracted, the variance estimated by
/// the square of the columns' halves' difference (docs/method.md, "The columns' noise").
struct LightFitProblem {
  const RayTracer* scene = nullptr;
  const ShadingVertices* vertices = nullptr;
  const std::vector<double>* y = nullptr;     ///< 3 per row
  const std::vector<double>* base = nullptr;  ///< 3 per row
  CauchyLoss loss{0.5};
  double alpha = 3, beta = 1;
  /// Per row: the segment of the surface it sees (0 ..), or -1 (its albedo held); null: every
  /// albedo held.
  const std::vector<int>* segment = nullptr;
  /// Per entry of y: how it bounds the model (LinearProblem::one_sided's Bound); null: every
  /// one exact.
  const std::vector<std::uint8_t>* one_sided = nullptr;
  /// Whether the residual r of entry i passes its bound on its free side (it then counts 0).
  bool Passes(std::size_t i, double r) const { return one_sided && PassesBound((*one_sided)[i], r); }
  /// y - model with what passes a bound counted as 0.
  double RowResidual(std::size_t i, double model) const {
    const double r = (*y)[i] - model;
    return one_sided ? BoundedResidual((*one_sided)[i], r) : r;
  }
  bool debiased = false;
  /// E at these lights; `sse`, when given, receives the sum of squared residuals.
  double Value(const std::vector<Light>& lights, double* sse = nullptr) const;
  /// The same with the lights' unit columns given (as UnitColumn makes them on these
  /// vertices: e.g. from a cache; without spreads, not debiased).
  double Value(const std::vector<Light>& lights, const std::vector<SplitColumn>& columns,
               double* sse = nullptr) const;
};

/// Every stride-th row of a fitting problem (stride = rows / max_rows rounded up; 1, the
/// problem itself, when it has no more): its vertices, observations and base, the activation
/// penalty divided by the stride so that it weighs against the data term as on all rows.
/// Where a share of the rows is enough to move the lights (each column on it costs that
/// share); its E times the stride estimates the whole problem's.
struct LightFitSubset {
  LightFitSubset(const LightFitProblem& full, std::size_t max_rows);
  LightFitSubset(const LightFitSubset&) = delete;
  LightFitSubset& operator=(const LightFitSubset&) = delete;
  int stride = 1;
  ShadingVertices vertices;
  std::vector<double> y, base;
  std::vector<int> segment;
  std::vector<std::uint8_t> one_sided;
  LightFitProblem problem;
};

/// A segment's albedo is left free only over at least this many rows (fewer fit their own
/// shading as well as any light's).
constexpr int kMinSegmentRows = 32;
/// The free albedo's multiplier is kept within [1 / kMaxSegmentMultiplier, kMaxSegmentMultiplier].
constexpr double kMaxSegmentMultiplier = 8;

/// The albedo multipliers of LightFitProblem's segments for a model (3 per row: what the
/// lights and base render), 3 per row (1 where the row's albedo is held): per segment and
/// channel the m minimizing sum rho(y - m model) over its rows, by reweighted least squares
/// (4 passes from 1), kept within kMaxSegmentMultiplier; a row of one_sided whose bound the
/// pass's multiplier keeps is left out of that pass (it would pull the albedo towards its clip
/// level), one it breaks counts as a measurement. `noise` (3 per row, or empty): the
/// model's halves' difference, whose square is taken from the model's (debiased).
std::vector<double> SegmentMultipliers(const LightFitProblem& problem, const std::vector<double>& model,
                                       const std::vector<double>& noise = {});

/// A directional light's scale `a` and a uniform sky's radiance `b` in one channel, fitted
/// together to t = a x + b s (x the light's column, s the sky's, t what the other lights leave)
/// by instrumental variables: z, an independently traced column of the light, instruments x
/// (docs/method.md, "The sky"). Each entry is weighted by the loss at the fit r = t - a0 x; an
/// entry of `one_sided` (null: every one exact) whose bound holds there is left out (a clipped
/// sunlit pixel says only "at least this bright"). Returns (a, b); where the sky does not come
/// out positive, (the light alone, 0); where nothing is weighed, (a0, 0).
Eigen::Vector2d FitLightBesideSky(const std::vector<float>& x, const std::vector<float>& z,
                                  const std::vector<double>& s, const std::vector<double>& t, double a0,
                                  const CauchyLoss& loss, const std::vector<std::uint8_t>* one_sided,
                                  std::size_t first = 0, std::size_t step = 1);

/// Called after each accepted step of a fit: (step, E, sum of squared residuals, lights).
using LightFitLog = std::function<void(int, double, double, const std::vector<Light>&)>;

/// Levenberg-Marquardt's damped steps of one iteration, (H + mu diag H) s = g (g: the
/// descent direction, J^T W r), and the damping that keeps a step within a length: where the
/// fit rejects a step, RefineLights retries it a quarter as long. Raising mu tenfold at a time
/// can leave the step as it was (along a valley whose curvature is far below the diagonal's:
/// a lamp's distance against its intensity), and each retry traces the columns again.
class DampedStep {
 public:
  DampedStep(Eigen::MatrixXd H, Eigen::VectorXd g);
  /// The step at *mu, *mu raised (doubled at a time) until the step's Length is at most
  /// `radius`; non-finite where no damping gives a finite step.
  Eigen::VectorXd Within(double radius, double* mu) const;
  /// The step's length in the damping's metric, sqrt(sum H_aa s_a^2).
  double Length(const Eigen::VectorXd& s) const { return std::sqrt(s.cwiseProduct(s).dot(d_)); }
  /// What the Gauss-Newton model says the step lowers the objective by: g.s - s.H.s / 2.
  double PredictedDrop(const Eigen::VectorXd& s) const { return g_.dot(s) - 0.5 * s.dot(H_ * s); }

 private:
  Eigen::VectorXd At(double mu) const;
  Eigen::MatrixXd H_;
  Eigen::VectorXd g_, d_;
};

/// Levenberg-Marquardt on the lights' shapes (ShapeDims each: a position, a direction's
/// tangent plane) and scales together, iteratively reweighted for the loss, the analytical
/// derivative of the columns (visibility held fixed), scales kept >= 0; a step is taken
/// only if E falls (a rejected one retried a quarter as long, DampedStep); it stops where a
/// step lowers E by less than `min_drop` of it, or where the model predicts it would (such a
/// step is not traced). Returns the iterations taken; `lights` holds the best found.
int RefineLights(const LightFitProblem& problem, std::vector<Light>* lights, int max_iterations = 12,
                 const LightFitLog& log = {}, double min_drop = 1e-6);

/// Each light's place's mean squared error from its columns' Monte Carlo noise (docs/method.md,
/// "Uncertainty"): the lights refitted (RefineLights, `iterations` steps from `lights`, the
/// rest of `problem` held) on the whole and on each of the kPathParts parts of its vertices'
/// paths apart (PartOf). Each part's noise is kPathParts times the whole's, so the parts'
/// places' sample covariance over kPathParts estimates the whole's (kPathParts - 1 degrees
/// of freedom: two halves' d d^T / 4 is of rank one, and says nothing across d). The noise
/// also pulls a lamp (errors in variables: about one over the paths, docs/benchmarks.md
/// session 36): a part's pull is kPathParts times the whole's, so the parts' mean lies
/// kPathParts - 1 pulls b from the whole's refit, and b b^T is added (the region is of the
/// error, not only of the spread; the lamp is not moved). `pull`, when given, receives b per
/// light. Zero for the other kinds, and for all when the vertices' parts were not kept or a
/// refit is not finite.
std::vector<Eigen::Matrix3d> PartsCovariance(LightFitProblem problem, const std::vector<Light>& lights,
                                             int iterations, std::vector<Eigen::Vector3d>* pull = nullptr);

/// A compass search's schedule: steps of `start` CompassUnits (a lamp: its distance from
/// the centre; a direction: a radian), halved when no move lowers the energy, down to
/// `stop`; at most `max_evaluations` columns a light (besides one for each other light).
struct CompassOptions {
  double start = 0.02, stop = 0.002;
  int max_evaluations = std::numeric_limits<int>::max();
  /// Write a light's scale refitted where it stands back even when it does not move (the
  /// directional light's search; a lamp keeps its intensity unless it moves).
  bool refit_unmoved = false;
};

/// A compass search for each light's shape in turn (its CompassMoves at each step), its
/// scale refitted at each place by reweighted least squares, the other lights held: the
/// shadows' edges move with the light, which RefineLights' derivative cannot see. A light
/// is changed only where it moves. Returns the moves taken; `log` is called after each.
int SearchLights(const LightFitProblem& problem, std::vector<Light>* lights, const Eigen::Vector3d& centre,
                 const CompassOptions& options, const LightFitLog& log = {});

/// The energy of a light at its shape, what `others` render (3 per row, or empty) held and
/// its scale refitted there by reweighted least squares (4 passes from its scale);
/// `sse` receives the sum of squared residuals.
double RefitScale(const LightFitProblem& problem, const SplitColumn& others, Light* light, double* sse);
/// The same with the light's unit column given (e.g. from a cache), its scale `scale`.
double RefitScale(const LightFitProblem& problem, const SplitColumn& column, const SplitColumn& others,
                  Eigen::Vector3d* scale, double* sse);

/// A light's size (a lamp's radius) chosen by its loss: `loss(size, scale)` is the energy
/// with the light at that size, its scale refitted there (written to `scale`).
using SizeLoss = std::function<double(double size, Eigen::Vector3d* scale)>;
struct SizeChoice {
  double size = 0, loss = 0;  ///< the size chosen (0: a point, a sharp light) and its loss
  double zero_loss = 0;       ///< the loss at size 0
  Eigen::Vector3d scale = Eigen::Vector3d::Zero();  ///< the scale refitted at the size chosen
};
/// The lowest loss over 0 and a doubling grid (first, 2 first, ... 2^(steps-1) first), then,
/// unless that is 0 or the widest ("at least this wide": a sun there is left to the map),
/// refined by `refinements` parabolas in the log of the size through the best size and its
/// neighbours (Brent's bracket kept: the loss must be smooth in the size, the shadow rays'
/// pattern fixed); the first's lower neighbour is half of it. A grid alone leaves the size up
/// to a factor of √2 off, and the shadows' edges place the light by its penumbrae (a 5 cm
/// lamp taken for 3.8 cm was 2 mm off across its ray where its region is 0.4 mm wide).
/// A size is taken only where it lowers the loss below (1 - min_gain) of size 0's.
SizeChoice ChooseSize(const SizeLoss& loss, double first, int steps, int refinements = 3, double min_gain = 0.005);

/// The widest angular radius FitAngularRadius tries (degrees).
constexpr double kMaxAngularRadiusDeg = 8;

/// The angular radius (soft shadows) of a directional light by ChooseSize (0 and 0.25 to
/// kMaxAngularRadiusDeg, doubling, then refined), its irradiance refitted at each, the rest
/// held: the lowest energy wins when it beats the sharp light's by 0.5 %. Returns the radius
/// (radians).
double FitAngularRadius(const LightFitProblem& problem, DirectionalLight* light);

}  // namespace lp
