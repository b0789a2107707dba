#pragma once
/// The lightprobe window: GLFW + Dear ImGui (OpenGL 3.3 core) over a Session. Panels for
/// the source and live previews, reconstruction, Estimate (settings, progress, the
/// error-against-time plot, Cancel, Export), the lit mesh in 3D and the environment map.
#include <string>

#include "estimation/estimator.h"
#include "ui/session.h"

namespace lp::ui {

struct ViewerOptions {
  /// What to open: "" = an attached camera, else the bundled demo (SessionOptions::demo_input).
  std::string input;
  /// A command file run while the window is live (tests, benchmarks; docs/viewer.md).
  std::string script;
  int width = 1280, height = 720;
  SessionOptions session;
  EstimateOptions estimate;  ///< the Estimate panel's defaults
};

/// Runs the window until it is closed or the script says quit; returns the exit code
/// (0, or 1 when a script command failed). Closing stops the estimate and playback and
/// waits for an export in progress. Throws InputError when no window can be opened
/// (no display), pointing to --headless.
int RunViewer(const ViewerOptions& options);

}  // namespace lp::ui
