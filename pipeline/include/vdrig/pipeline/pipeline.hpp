// The stages of vdrig chained on a session folder (files: capture/session_layout.hpp). Each stage reads what the
// previous one wrote, so each can be run alone (vdrig capture / hdr / calib extrinsics / obsmap / fit) or all at once
// (vdrig demo): capture -> HDR -> geometry -> observation map -> fit (fitting/fit_map.hpp) -> render and compare.
#pragma once

#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/pipeline/capture_stage.hpp"
#include "vdrig/pipeline/compare_stage.hpp"
#include "vdrig/pipeline/geometry_stage.hpp"
#include "vdrig/pipeline/hdr_stage.hpp"
#include "vdrig/pipeline/obsmap_stage.hpp"
#include "vdrig/pipeline/render_stage.hpp"
