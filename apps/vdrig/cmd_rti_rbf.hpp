// `vdrig rti rbf`: relight's default basis (PCA planes + RBF light interpolation) fitted to a stack (or an imported
// one) and written as the relight folder OpenLIME loads (rti/pca_basis.hpp). A command of its own rather than a model
// of `vdrig rti fit`: the basis belongs to the stack (PCA over its texels), so there is no per-texel parameter map to
// store between a fit and an export.
#pragma once

#include <CLI/CLI.hpp>

namespace vdrig::app {

/// Adds `rbf` under the `rti` subcommand (called from cmd_rti.cpp).
void add_rti_rbf_command(CLI::App& rti);

}  // namespace vdrig::app
