#include "estimation/truth_scorer.h"

#include "scene/mesh.h"

namespace lp {

std::shared_ptr<const TruthScorer> TruthScorer::FromBundle(const SceneBundle& bundle, double far) {
  if (!bundle.truth_json) return nullptr;
  Eigen::Vector3d centre;
  double radius = 1;
  BoundingSphere(bundle.mesh, &centre, &radius);
  std::vector<TruthLight> truth = ParseTruthLights(*bundle.truth_json, (bundle.dir / "truth.json").string());
  CentreTruthLights(&truth, centre);
  return std::make_shared<TruthScorer>(std::move(truth), centre, far * radius);
}

TruthScorer::TruthScorer(std::vector<TruthLight> truth, const Eigen::Vector3d& centre, double far_m)
    : truth_(std::move(truth)), centre_(centre), far_m_(far_m) {}

void TruthScorer::Score(ConvergenceRow* row, const EnvMap& env, const std::vector<double>& env_lambda,
                        const std::vector<PointLight>& points, const std::vector<DirectionalLight>& suns) const {
  if (truth_.empty()) return;
  row->angular_error_deg = DominantAngularErrorDeg(env, env_lambda, points, centre_, truth_, suns);
  row->position_error_m = WorstPositionError(points, truth_, centre_, far_m_);
}

void TruthScorer::Conclude(EstimateResult* r) const {
  if (truth_.empty()) return;
  r->final_angular_error_deg =
      DominantAngularErrorDeg(r->env, r->lambda, r->point_lights, centre_, truth_, r->directional_lights);
  r->final_position_error_m =
      WorstPositionError(r->point_lights, truth_, centre_, far_m_, &r->final_position_error_share);
}

}  // namespace lp
