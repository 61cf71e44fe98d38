// Fitting an imported synthetic stack (synthetic_stack.hpp) the same way in every RTI test.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "vdrig/fitting/fit_map.hpp"

namespace vdrig::test {

/// The map of `model` fitted to the observation map `obsmap` (an imported stack), on two threads; fails the
/// calling test (and returns an empty map) when the file cannot be read or the fit fails.
inline fitting::ParameterMap fit_imported_stack(const std::filesystem::path& obsmap, const std::string& model) {
  auto reader = fitting::ObsMapReader::open(obsmap);
  if (!reader) {
    ADD_FAILURE() << reader.error().describe();
    return {};
  }
  fitting::MapFitOptions options;
  options.model = fitting::parse_model(model).value();
  options.threads = 2;
  auto map = fitting::fit_parameter_map(reader.value(), options);
  if (!map) {
    ADD_FAILURE() << map.error().describe();
    return {};
  }
  return std::move(map.value());
}

}  // namespace vdrig::test
