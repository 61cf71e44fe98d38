#include "vdrig/pipeline/capture_stage.hpp"

#include "vdrig/capture/capture.hpp"
#include "vdrig/capture/plan.hpp"
#include "vdrig/capture/schemes.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/sim/scene.hpp"
#include "vdrig/sim/sim_rig.hpp"

namespace vdrig::pipeline {

Result<capture::Session> capture_session(const CaptureRequest& req) {
  auto logger = log::get("capture");
  auto rig = sim::simulator_and_hardware_backends().make_rig(req.rig_config);
  if (!rig) return rig.error();
  auto samples = capture::generate(req.scheme);
  if (!samples) return samples.error();
  // Aimed as `vdrig capture` aims: with the config's stated "geometry", else the ideal rig at its distance; never
  // with the simulator's hidden truth (an imperfect simulated rig misses its planned directions until calibrated).
  auto geometry = capture::geometry_from_rig_config(req.rig_config);
  if (!geometry) return geometry.error();
  const auto plan = capture::plan_targets(geometry.value(), rig->stage->spec(), samples->directions);
  for (const auto& u : plan.unreachable) {
    const SphericalDir s = spherical_from_direction(u.direction);
    logger->warn("direction {} (azimuth {:.1f} deg, zenith {:.1f} deg) is unreachable within the axis limits", u.index,
                 rad_to_deg(s.azimuth_rad), rad_to_deg(s.zenith_rad));
  }
  capture::Manifest manifest;
  manifest.rig_config = req.rig_config;
  manifest.scheme = req.scheme;
  std::string bracket = "fixed:";
  for (size_t i = 0; i < req.exposures_s.size(); ++i) bracket += (i ? "," : "") + std::to_string(req.exposures_s[i]);
  manifest.bracket = bracket;
  manifest.exposures_s = req.exposures_s;
  manifest.extra = req.manifest_extra;
  for (const auto& t : plan.reachable)
    manifest.views.push_back({static_cast<int>(manifest.views.size()), t.direction, t.pan_tilt});
  if (req.rig_config.contains("sim")) {
    // The sample's size is the rig's configuration (what a user measures with a ruler), not calibration output.
    auto config = sim::SimConfig::from_json(req.rig_config["sim"]);
    if (!config) return config.error();
    auto scene = sim::make_scene(config->scene);
    if (!scene) return scene.error();
    manifest.surface_width_mm = scene->width_mm;
    manifest.surface_height_mm = scene->height_mm;
  }
  auto session = capture::Session::create(req.out_dir, manifest);
  if (!session) return session.error();
  VDRIG_TRY(rig->stage->home());
  capture::CaptureOptions options;
  options.exposures_s = req.exposures_s;
  options.on_progress = [&](const capture::CaptureProgress& p) {
    if (req.on_view) req.on_view(p.views_done, p.views_total);
  };
  VDRIG_TRY(capture::run_capture(rig.value(), session.value(), options));
  return session;
}

}  // namespace vdrig::pipeline
