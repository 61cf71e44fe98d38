// Adaptive sampling's planner (capture/adaptive.hpp runs the loop): a coarse observation map of the views captured
// so far, per texel Phong lobes or a ggx:iso lobe (`model=`), and the next views chosen where the lobes are poorly
// constrained and where the hemisphere has gaps, weighed against the stage's move time (docs/sampling.md, "adaptive").
//
// It reads the frames as they are (no HDR merge, no marker calibration: it runs between batches, in seconds): each
// view's least exposed unclipped frame divided by its exposure, posed by the rig geometry the capture aims with at
// the measured pan/tilt, projected with the camera intrinsics of the adaptive settings' `camera` (or
// SESSION/calib/camera.yml). Coarse figures for ranking directions, not the session's calibrated measurement.
#pragma once

#include <memory>

#include "vdrig/capture/adaptive.hpp"

namespace vdrig::pipeline {

/// The planner above. Deterministic: the same completed views and settings give the same batch.
std::unique_ptr<capture::ViewPlanner> make_coarse_fit_planner();

/// Registers make_coarse_fit_planner as the planner of `adaptive:` schemes (capture::register_view_planner_factory).
void register_adaptive_planner();

}  // namespace vdrig::pipeline
