#pragma once
/// One press of Estimate: its own thread, cancel token and status. The estimator thread
/// (at a lower OS priority, so the window keeps its frame rate) builds the scene from the
/// snapshot the session's worker took, runs Estimate on it, then refines the lit shading
/// of its mesh until its noise is `lit_noise` (or it has `lit_samples`), then renders its
/// keyframes clean (pass by pass). Destroying a job cancels it and joins its thread.
#include <atomic>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include "common/timer.h"
#include "estimation/estimator.h"
#include "reconstruction/reconstruction_run.h"
#include "ui/status.h"

namespace lp::ui {

/// A scene to estimate: a loaded bundle, or a reconstruction's snapshot still to finish.
using SceneSource = std::variant<std::shared_ptr<const SceneBundle>, ReconstructionRunSnapshot>;

class EstimateJob {
 public:
  static constexpr double kLitVertices = 250000;
  struct Settings {
    EstimateOptions options;
    /// The lit shading stops refining here at the latest: samples per vertex of a mesh of
    /// kLitVertices or more; a smaller mesh gets as many more as the same paths allow (a
    /// 1,500-vertex box needs thousands for 1 %: its vertices are too far apart to smooth).
    int lit_samples = 256;
    /// ... or once its relative noise (LitShading::noise) is this (the fit's bias, about 1 % on
    /// a scan's rough spots, comes on top: docs/method.md).
    double lit_noise = 0.007;
    const Stopwatch* clock = nullptr;  ///< the session's clock (outlives the job)
    double pressed_at = 0;        ///< on `clock`: when Estimate was pressed
    /// Where the status's version counters start (the window re-uploads what changed).
    std::uint64_t version = 0, lit_version = 0;
    /// A live estimate (Session::SetLive): what the last job shows (its lights, map, scene,
    /// lit shading and result), shown until this one has its own (null: nothing).
    std::shared_ptr<const EstimateStatus> shown;
    bool live = false;
    int live_index = 0;
    bool preview = false;  ///< a live preview (LivePreview: the options are already its)
  };

  /// A job waiting for its scene: kPreparing, "taking a snapshot of the scene".
  explicit EstimateJob(Settings settings);
  /// Cancels and joins.
  ~EstimateJob();
  EstimateJob(const EstimateJob&) = delete;
  EstimateJob& operator=(const EstimateJob&) = delete;

  /// Starts the estimate of `scene` on the job's thread; `retired` (jobs replaced by this
  /// one, already cancelled) are joined there first, not on the caller's thread.
  void Start(SceneSource scene, std::vector<std::unique_ptr<EstimateJob>> retired);
  /// The scene could not be taken: the job ends failed with `message`.
  void Fail(const std::string& message);
  /// Stops the job at its next check (within a round's 64 pixels, a solver iteration, a
  /// lit-shading step); a job still preparing ends cancelled at once.
  void Cancel();
  bool cancelled() const { return cancel_.load(); }
  /// Cancels and lets go of what its status holds (scene, result, shading): a replaced job
  /// may wait a while for the thread that joins it.
  void Retire();
  EstimateStatus status() const;

 private:
  void Run(SceneSource source);
  /// Builds the scene (a snapshot is finished here) and estimates it; null when it ended.
  std::shared_ptr<const EstimateResult> EstimateScene(SceneSource source, std::shared_ptr<const SceneBundle>* scene);
  EstimateOptions Callbacks();
  void RefineLit(const RayTracer& tracer, const SceneBundle& scene, const EstimateResult& result);
  void CleanRender(const RayTracer& tracer, const SceneBundle& scene, const EstimateResult& result);
  template <typename F>
  void Update(F f) {
    std::lock_guard<std::mutex> lock(mutex_);
    f(status_);
  }
  double SincePressed() const { return settings_.clock->Seconds() - settings_.pressed_at; }

  Settings settings_;
  std::atomic<bool> cancel_{false};
  mutable std::mutex mutex_;
  EstimateStatus status_;
  std::thread thread_;
};

}  // namespace lp::ui
