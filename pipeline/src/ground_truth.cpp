#include "ground_truth.hpp"

#include "vdrig/sim/scene.hpp"
#include "vdrig/sim/sim_rig.hpp"

namespace vdrig::pipeline {

Result<std::optional<GroundTruth>> ground_truth_of(const nlohmann::json& rig_config) {
  if (!rig_config.contains("sim")) return std::optional<GroundTruth>();
  auto config = sim::SimConfig::from_json(rig_config["sim"]);
  if (!config) return config.error();
  auto scene = sim::make_scene(config->scene);
  if (!scene) return scene.error();
  GroundTruth truth;
  truth.camera = config->camera;
  truth.geometry = config->geometry;
  truth.response = config->sensor.response;
  truth.markers.centres_mm = scene->marker_centres_mm();
  if (!scene->markers.empty()) truth.markers.radius_mm = scene->markers.front().radius_mm;
  truth.surface_width_mm = scene->width_mm;
  truth.surface_height_mm = scene->height_mm;
  return std::optional<GroundTruth>(std::move(truth));
}

}  // namespace vdrig::pipeline
