#pragma once
/// Synthetic RGB-D frames as a camera delivers them: the estimation core renders a known
/// scene along a known trajectory (estimation/synth.h); these are its frames as 8-bit sRGB
/// colour and millimetre depth, registered, with the true poses. The basis of the
/// reconstruction tests (library lp_capture_synth: it links the renderer).

#include <vector>

#include "capture/frame.h"
#include "estimation/synth.h"

namespace lp {

/// 8-bit sRGB colour (clipped at 1), depth in millimetres (0 = none or beyond 65.535 m),
/// registered, the true pose, timestamps at 30 Hz.
std::vector<RgbdFrame> ToRgbdFrames(const std::vector<SynthFrame>& frames);

}  // namespace lp
