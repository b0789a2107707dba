// `lightprobe evaluate`: a headless run scored against a scan's ground truth (app/scan_evaluation.h).
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "app/commands.h"
#include "app/scan_evaluation.h"
#include "common/atomic_file.h"
#include "common/parallel.h"

namespace lp::app {
namespace fs = std::filesystem;

Run AddEvaluate(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "evaluate", "score a headless run (RUN/scene, RUN/estimate) against a scan's ground truth (truth.json, "
                  "gt_mesh.ply, holdout/)");
  auto run = std::make_shared<std::string>();
  auto truth = std::make_shared<std::string>();
  auto spp = std::make_shared<int>(64);
  auto threads = std::make_shared<int>(0);
  cmd->add_option("RUN_DIR", *run, "what `lightprobe --headless SCAN --out RUN_DIR` wrote")->required();
  cmd->add_option("--truth", *truth,
                  "the scan's directory (truth.json, gt_mesh.ply and holdout/, each scored when there; a real "
                  "recording's held-out frame: holdout/ alone)")
      ->required();
  cmd->add_option("--spp", *spp, "samples per pixel of the held-out view's relit render")->capture_default_str();
  cmd->add_option("--threads", *threads, "worker threads (0 = all cores)")->capture_default_str();
  return [=] {
    if (*spp < 1) throw InputError("evaluate: --spp must be at least 1");
    ThreadLimit limit(*threads);
    const ScanScore s = EvaluateScan(*truth, *run, *spp);
    if (s.mesh)
      std::printf("mesh: %.1f mm median, %.1f mm at the 90th percentile from the true surface; %.1f %% of what the "
                  "keyframes see within 2 cm\n",
                  1e3 * s.mesh->median_m, 1e3 * s.mesh->p90_m, 100 * s.mesh->complete_2cm);
    for (std::size_t k = 0; k < s.lamps.size(); ++k) {
      const LampScore& l = s.lamps[k];
      std::printf("lamp %zu: %.1f cm from the nearest estimate (%.1f %% of its %.2f m from the room's centre); "
                  "intensity x%.2f, light x albedo x%.2f\n",
                  k, 100 * l.error_m, 100 * l.share, l.distance_m, l.intensity_ratio, l.light_times_albedo);
    }
    for (std::size_t k = 0; k < s.suns.size(); ++k) {
      if (std::isfinite(s.suns[k].angle_deg))
        std::printf("sun %zu: %.2f degrees from the nearest directional light, irradiance x%.2f\n", k,
                    s.suns[k].angle_deg, s.suns[k].irradiance_ratio);
      else
        std::printf("sun %zu: no directional light estimated\n", k);
    }
    for (std::size_t k = 0; k < s.emitters.size(); ++k)
      std::printf("glowing surface %zu (%.3g m^2): the estimate overlapping it most by IoU %.2f, power x%.2f\n", k,
                  s.emitters[k].true_area, s.emitters[k].iou, s.emitters[k].power_ratio);
    if (s.estimated_emitters > 0)
      std::printf("%d emitter(s) estimated; the largest spurious one emits %.1f %% of their power\n",
                  s.estimated_emitters, 100 * s.spurious_emitter_share);
    if (std::isfinite(s.spurious_share))
      std::printf("%d lamp(s) estimated; the largest spurious one gives %.1f %% of their light at the centre\n",
                  s.estimated_lamps, 100 * s.spurious_share);
    else
      std::printf("%d lamp(s) estimated (no truth.json: none scored)\n", s.estimated_lamps);
    if (s.albedo_samples > 0)
      std::printf("albedo's scale (estimated / true) %.3f over %d pixels; its error once the scale is undone %.3f\n",
                  s.albedo_scale, s.albedo_samples, s.albedo_error);
    if (std::isfinite(s.held_out_relit)) {
      std::printf("held-out view relit: relative RMSE %.3f (%.3f over the %.0f %% of its pixels the scan covers",
                  s.held_out_relit, s.held_out_relit_covered, 100 * s.held_out_covered);
      if (std::isfinite(s.held_out_relit_true_albedo))
        std::printf("; %.3f there with the true albedo in place of the colour map", s.held_out_relit_true_albedo);
      std::printf(")\n");
    }
    if (std::isfinite(s.held_out_relit_blurred))
      std::printf("held-out view, both blurred by %.0f px: %.3f (the light's part); what the blur takes away: %.3f (the "
                  "colour map's sharpness and registration)\n",
                  kSplitBlurPx, s.held_out_relit_blurred, s.held_out_colour_map_part);
    const fs::path out = fs::path(*run) / "evaluation.json";
    WriteTextAtomically(out, ScanScoreJson(s));
    const bool reported = AddToReport(*run, s);
    std::printf("wrote %s%s in %.1f s\n", out.c_str(), reported ? " and its \"evaluation\" in estimate/report.json" : "",
                s.seconds);
  };
}

}  // namespace lp::app
