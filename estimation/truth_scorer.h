#pragma once
/// An estimate scored against a ground truth (truth.json) as it goes: an observer that
/// whoever has the truth attaches (EstimateOptions::scorer: the command line and the viewer
/// from the bundle's truth.json, the tests from theirs). The estimator never reads
/// truth.json; it hands the scorer every convergence row and its result.
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "estimation/estimator.h"
#include "estimation/truth.h"
#include "scene/scene_bundle.h"

namespace lp {

class TruthScorer {
 public:
  /// The lights of `bundle`'s truth.json (nullptr without one), their directions taken from
  /// the centre of the bundle's mesh's bounding sphere (as the estimator's scene centre); a
  /// point light farther than `far` of its radii is not a near light (PointLightOptions::far).
  static std::shared_ptr<const TruthScorer> FromBundle(const SceneBundle& bundle, double far = 5);
  TruthScorer(std::vector<TruthLight> truth, const Eigen::Vector3d& centre, double far_m);

  /// The row's dominant direction error (`lighting`, its map over `env`) and its worst near
  /// light's position error.
  void Score(ConvergenceRow* row, const EnvMap& env, const Lighting& lighting) const;
  /// The same for the result (its final_* errors).
  void Conclude(EstimateResult* result) const;

 private:
  std::vector<TruthLight> truth_;
  Eigen::Vector3d centre_;
  double far_m_;
};

}  // namespace lp
