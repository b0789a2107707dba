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

void TruthScorer::Score(ConvergenceRow* row, const EnvMap& env, const Lighting& lighting) const {
  if (truth_.empty()) return;
  const std::vector<PointLight> points = lighting.Of<PointLight>();
  row->angular_error_deg =
      DominantAngularErrorDeg(env, lighting.map, points, centre_, truth_, lighting.Of<DirectionalLight>());
  row->position_error_m = WorstPositionError(points, truth_, centre_, far_m_);
}

void TruthScorer::Conclude(EstimateResult* r) const {
  if (truth_.empty()) return;
  const Lighting& l = r->lighting;
  const std::vector<PointLight> points = l.Of<PointLight>();
  r->final_angular_error_deg =
      DominantAngularErrorDeg(r->env, l.map, points, centre_, truth_, l.Of<DirectionalLight>());
  r->final_position_error_m = WorstPositionError(points, truth_, centre_, far_m_, &r->final_position_error_share);
}

}  // namespace lp
