// `vdrig render MAP [--session S --view I | --azimuth A --zenith Z --distance D] --out F.png|F.exr`: one frame of a
// parameter map through the viewer's shader, headless (viewer/headless.hpp).
// `vdrig inspect MAP --session S --texel S,T --out plot.png`: the texel inspector's plot (viewer/texel_inspector.hpp).
// docs/viewer.md describes both.
#include <cstdio>
#include <memory>
#include <string>

#include "commands.hpp"
#include "session_data.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/viewer/headless.hpp"
#include "vdrig/viewer/interactive.hpp"
#include "vdrig/viewer/texel_inspector.hpp"

namespace vdrig::app {
namespace {

struct RenderArgs {
  std::string map, session, out, size = "1024x768";
  int view = -1, samples = 2;
  double azimuth_deg = 270.0, zenith_deg = 0.0, distance_mm = 2500.0, gamma = 1.0;
  bool orbit_given = false;
};

Status run_render(const RenderArgs& a) {
  auto map = fitting::ParameterMap::read(a.map);
  if (!map) return map.error();
  CameraModel camera;
  ViewPose pose;
  if (a.view >= 0) {
    if (a.session.empty()) return make_error(ErrorCode::kInvalidArgument, "--view needs --session");
    if (a.orbit_given)
      return make_error(ErrorCode::kInvalidArgument, "--view and --azimuth/--zenith/--distance exclude each other");
    auto data = open_session_data(a.session);
    if (!data) return data.error();
    VDRIG_TRY(data->check_view(a.view));
    camera = data->geometry.camera;
    pose = data->geometry.poses[a.view];
  } else {
    if (!(a.zenith_deg >= 0 && a.zenith_deg <= 89) || !(a.distance_mm > 0))
      return make_error(ErrorCode::kInvalidArgument, "--zenith must be in [0, 89] degrees and --distance positive");
    if (!a.session.empty()) {
      auto data = open_session_data(a.session);
      if (!data) return data.error();
      camera = data->geometry.camera;
    } else {
      auto size = parse_resolution(a.size);
      if (!size) return make_error(ErrorCode::kInvalidArgument, "--size must be WxH pixels, e.g. 1024x768");
      // The viewer's free camera (viewer::default_pinhole: the surface framed from 2500 mm).
      camera = viewer::default_pinhole(map->width_mm(), map->height_mm(), size->first, size->second);
    }
    pose = viewer::orbit_pose(Vec3d::Zero(), deg_to_rad(a.azimuth_deg), deg_to_rad(a.zenith_deg), a.distance_mm);
  }
  viewer::RenderSettings settings;
  settings.samples_per_axis = a.samples;
  auto radiance = viewer::render_map_radiance(map.value(), camera, pose, settings);
  if (!radiance) return radiance.error();
  VDRIG_TRY(viewer::write_frame(a.out, radiance.value(), a.gamma));
  std::printf("%s (%dx%d, %s) -> %s\n", map->model().name().c_str(), camera.width, camera.height,
              a.view >= 0 ? ("captured view " + std::to_string(a.view)).c_str() : "orbit", a.out.c_str());
  return Status::ok();
}

struct InspectArgs {
  std::string map, session, texel, out;
  int width = 960, height = 540;
};

Status run_inspect(const InspectArgs& a) {
  auto map = fitting::ParameterMap::read(a.map);
  if (!map) return map.error();
  auto texel = parse_texel(a.texel);
  if (!texel) return texel.error();
  const auto [s, t] = texel.value();
  if (s >= map->texels_s() || t >= map->texels_t())
    return make_error(ErrorCode::kInvalidArgument, "--texel " + a.texel + " is outside the map's " +
                                                       std::to_string(map->texels_s()) + "x" +
                                                       std::to_string(map->texels_t()) + " texels");
  if (a.width < 480 || a.height < 270 || a.width > 8192 || a.height > 8192)
    return make_error(ErrorCode::kInvalidArgument, "--plot-width x --plot-height must be within 480x270 .. 8192x8192");
  auto data = open_session_data(a.session);
  if (!data) return data.error();
  auto obs = data->observations(map.value(), s, t);
  if (!obs) return obs.error();
  const auto inspection = viewer::inspect_texel(map.value(), s, t, obs.value(), viewer::held_out_views(map.value()));
  VDRIG_TRY(write_png(a.out, viewer::plot_inspection(inspection, a.width, a.height)));
  int near_circle = 0, held = 0;
  for (const auto& o : inspection.observations) {
    near_circle += o.off_circle_deg <= inspection.band_deg ? 1 : 0;
    held += o.held_out ? 1 : 0;
  }
  std::printf("texel %d,%d of %s: %zu observations (%d held out, %d near the great circle) -> %s\n", s, t,
              inspection.model.c_str(), inspection.observations.size(), held, near_circle, a.out.c_str());
  if (inspection.capped_lobes && *inspection.capped_lobes > 0)
    std::printf("  %s\n", viewer::capped_lobes_note(*inspection.capped_lobes).c_str());
  return Status::ok();
}

const CommandRegistrar kRender([](CLI::App& root) {
  auto a = std::make_shared<RenderArgs>();
  auto* cmd = root.add_subcommand(
      "render", "one frame of a parameter map through the viewer's shader, headless: tone-mapped PNG or linear EXR");
  cmd->add_option("map", a->map, "parameter map (OpenEXR, from vdrig fit)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--session", a->session, "session folder: its camera (and, with --view, a captured pose)");
  cmd->add_option("--view", a->view, "render from this captured view's pose (needs --session)");
  auto* az =
      cmd->add_option("--azimuth", a->azimuth_deg, "orbit azimuth, degrees (surface frame)")->capture_default_str();
  auto* zen =
      cmd->add_option("--zenith", a->zenith_deg, "orbit zenith, degrees (0 = straight above)")->capture_default_str();
  auto* dist = cmd->add_option("--distance", a->distance_mm, "orbit distance from the surface centre, mm")
                   ->capture_default_str();
  cmd->add_option("--size", a->size, "image size WxH without --session (the viewer's free camera)")
      ->capture_default_str();
  cmd->add_option("--gamma", a->gamma, "PNG tone mapping y = 1 - exp(-gamma x)")->capture_default_str();
  cmd->add_option("--samples", a->samples, "antialiasing sub-samples per pixel axis")
      ->capture_default_str()
      ->check(CLI::Range(1, 8));
  cmd->add_option("--out", a->out, "output image: .png (tone mapped, sRGB) or .exr (linear radiance R, G, B)")
      ->required();
  cmd->callback([a, az, zen, dist] {
    a->orbit_given = az->count() + zen->count() + dist->count() > 0;
    finish(run_render(*a));
  });

  auto i = std::make_shared<InspectArgs>();
  auto* inspect = root.add_subcommand(
      "inspect", "plot one texel: its observations, the model's curve through the peak, residuals, parameters");
  inspect->add_option("map", i->map, "parameter map (OpenEXR, from vdrig fit)")->required()->check(CLI::ExistingFile);
  inspect->add_option("--session", i->session, "the session the map was fitted from")->required();
  inspect->add_option("--texel", i->texel, "texel S,T (column, row of the map)")->required();
  inspect->add_option("--out", i->out, "plot PNG")->required();
  inspect->add_option("--plot-width", i->width, "plot width, pixels")->capture_default_str();
  inspect->add_option("--plot-height", i->height, "plot height, pixels")->capture_default_str();
  inspect->callback([i] { finish(run_inspect(*i)); });
});

}  // namespace
}  // namespace vdrig::app
