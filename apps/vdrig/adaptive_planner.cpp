// Gives `vdrig capture --scheme adaptive:N` the pipeline's planner (pipeline/adaptive_stage.hpp). Compiled only when
// the pipeline is built (apps/CMakeLists.txt): a capture-only vdrig refuses adaptive schemes with kUnsupported.
#include "vdrig/pipeline/adaptive_stage.hpp"

namespace {

const bool kRegistered = [] {
  vdrig::pipeline::register_adaptive_planner();
  return true;
}();

}  // namespace
