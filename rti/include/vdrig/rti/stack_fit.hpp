// Fitting an RTI stack straight from its photographs, in one pass and one process: what `vdrig rti fit STACK`
// runs, and why vdrig is faster than relight-cli on the same stack (docs/rti.md, "Speed").
//
// `vdrig rti import` + `rti fit` go through an observation-map file, which any model can fit (Phong's lobes
// included). For the models whose fit is one linear operator on a shared direction set (ReflectanceModel::
// linear_in_shared_directions: ptm:rgb, hsh:N, sh-*:N) that detour costs a transpose to disk and back. Here
// every photograph is opened at once and decoded a band of rows at a time (JPEG through libjpeg's scanline
// interface, so the stack is never whole in memory: 289 images of 1024 x 1024 take tens of MB, not 900), and each
// band is fitted with the model's own operator as one matrix product, on every core.
//
// The map is the one fit_parameter_map gives on the imported stack, channel for channel (parameters, rms.*, n,
// loo.* for models that report it; tests/rti/test_stack_fit.cpp compares them), with the import's conventions
// (import.hpp): texel (s, t) is crop column s and row H - 1 - t.
#pragma once

#include <filesystem>
#include <functional>
#include <opencv2/core.hpp>
#include <optional>

#include "vdrig/core/result.hpp"
#include "vdrig/fitting/fit_map.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/rti/import.hpp"

namespace vdrig::rti {

struct StackFitOptions {
  fitting::ModelPtr model;       // linear_in_shared_directions() (checked: kInvalidArgument otherwise)
  Linearisation linearisation;   // as import.hpp: the codes by default
  std::optional<cv::Rect> crop;  // in image pixels from the top-left corner; must lie inside the images
  int threads = 0;               // 0: every core
  fitting::MapFitOptions fit;    // model options (fit.model is ignored: `model` is)
  std::function<void(int rows_done, int rows_total)> on_progress;
};

/// Fits the stack whose .lp is `stack` (or the single .lp in the folder `stack`). Errors as import_stack (every
/// image is checked to exist before any is decoded; sizes must agree), plus kInvalidArgument for a model that is
/// not linear in shared directions (the message says to import the stack and fit the observation map instead).
Result<fitting::ParameterMap> fit_stack(const std::filesystem::path& stack, const StackFitOptions& options);

}  // namespace vdrig::rti
