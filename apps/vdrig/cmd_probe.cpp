// `vdrig probe info|lights|irradiance|render FILE`: inspect an equirectangular HDR light probe, extract median-cut
// lights or SH-9 irradiance coefficients as JSON, and render a diffuse sphere lit by it (probe/, docs/probe.md).
// `vdrig probe fuse A.exr:X,Y,Z B.exr:X,Y,Z ... --room ... --at X,Y,Z`: fuse probes on a box proxy at a new position.
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "commands.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/probe/fusion.hpp"
#include "vdrig/probe/median_cut.hpp"
#include "vdrig/probe/probe.hpp"
#include "vdrig/probe/sh_irradiance.hpp"
#include "vdrig/probe/shading.hpp"

namespace vdrig::app {
namespace {

Error usage(const std::string& m) { return make_error(ErrorCode::kInvalidArgument, m); }

// JSON files written here carry a format version (docs/conventions.md: every file format has one).
constexpr int kLightsFormatVersion = 1;
constexpr int kSh9FormatVersion = 1;

nlohmann::json rgb_json(const probe::Rgb& c) { return nlohmann::json::array({c.x(), c.y(), c.z()}); }

nlohmann::json angles_json(const Vec3d& d) {
  const SphericalDir s = spherical_from_direction(d);
  return {{"azimuth_deg", rad_to_deg(s.azimuth_rad)}, {"zenith_deg", rad_to_deg(s.zenith_rad)}};
}

Result<probe::Probe> load(const std::string& file, bool as_design_notes) {
  probe::LoadOptions o;
  o.azimuth = as_design_notes ? probe::FileAzimuth::kDesignNotes : probe::FileAzimuth::kPanorama;
  return probe::load_probe(file, o);
}

Status write_json(const std::string& out, const nlohmann::json& j) {
  VDRIG_TRY(write_file_atomic(out, j.dump(2) + "\n"));
  std::printf("wrote %s\n", out.c_str());
  return Status::ok();
}

Status run_info(const std::string& file, bool design_notes) {
  auto p = load(file, design_notes);
  if (!p) return p.error();
  const probe::Rgb power = probe::total_power(*p);
  const probe::BrightestPixel b = probe::brightest_pixel(*p);
  const SphericalDir s = spherical_from_direction(b.direction);
  std::printf("%s: light probe %d x %d (lat-long, %s azimuth)\n", file.c_str(), p->width(), p->height(),
              design_notes ? "design-notes" : "panorama");
  std::printf("  total power    %.6g %.6g %.6g (RGB, integral of L over 4 pi sr), luminance %.6g\n", power.x(),
              power.y(), power.z(), probe::luminance(power));
  std::printf("  brightest      azimuth %.2f deg, zenith %.2f deg (pixel %d, %d), radiance %.6g %.6g %.6g\n",
              rad_to_deg(s.azimuth_rad), rad_to_deg(s.zenith_rad), b.column, b.row, b.radiance.x(), b.radiance.y(),
              b.radiance.z());
  std::printf("  depth          %s\n", p->has_depth() ? "present" : "none");
  return Status::ok();
}

Status run_lights(const std::string& file, bool design_notes, int count, const std::string& out) {
  if (!probe::is_power_of_two(count)) return usage("--count must be a power of two, got " + std::to_string(count));
  auto p = load(file, design_notes);
  if (!p) return p.error();
  const auto lights = probe::median_cut(*p, count);
  nlohmann::json j = {{"format", "vdrig.probe.lights"},
                      {"version", kLightsFormatVersion},
                      {"probe", file},
                      {"method", "median cut (Debevec 2005)"},
                      {"power_unit",
                       "integral of radiance over the region (radiance x sr); E(n) = sum power max(0, "
                       "n.d)"},
                      {"lights", nlohmann::json::array()}};
  for (const auto& l : lights) {
    nlohmann::json e = angles_json(l.direction);
    e["direction"] = {l.direction.x(), l.direction.y(), l.direction.z()};
    e["power"] = rgb_json(l.power);
    e["solid_angle_sr"] = l.solid_angle_sr;
    j["lights"].push_back(e);
  }
  std::printf("%zu median-cut lights, total power %.6g (luminance)\n", lights.size(),
              probe::luminance(probe::total_power(*p)));
  return write_json(out, j);
}

Status run_irradiance(const std::string& file, bool design_notes, const std::string& out) {
  auto p = load(file, design_notes);
  if (!p) return p.error();
  const probe::Sh9 sh = probe::project_sh9(*p);
  nlohmann::json j = {
      {"format", "vdrig.probe.sh9"},
      {"version", kSh9FormatVersion},
      {"probe", file},
      {"basis", "real SH, design notes' normalisation with Condon-Shortley phase, i = l(l+1)+m"},
      {"radiance_coefficients", nlohmann::json::array()},
      {"cosine_factors", {probe::sh9_cosine_factor(0), probe::sh9_cosine_factor(1), probe::sh9_cosine_factor(2)}},
      {"note", "E(n) = sum_i cosine_factors[l(i)] * radiance_coefficients[i] * y_i(n)"}};
  for (const auto& c : sh.coeffs) j["radiance_coefficients"].push_back(rgb_json(c));
  return write_json(out, j);
}

Result<probe::Rgb> parse_albedo(const std::string& text) {
  std::stringstream ss(text);
  probe::Rgb a;
  char comma1 = 0, comma2 = 0;
  if (!(ss >> a.x() >> comma1 >> a.y() >> comma2 >> a.z()) || comma1 != ',' || comma2 != ',' || !ss.eof())
    return usage("--albedo must be R,G,B (each in [0, 1]), got " + text);
  return a;
}

struct RenderArgs {
  std::string file, albedo = "0.8,0.8,0.8", mode = "sh", out = "sphere.png";
  int size_px = 256, count = 256;
  double gamma = 0;
  bool design_notes = false;
};

Status run_render(const RenderArgs& a) {
  probe::SphereRenderOptions o;
  auto albedo = parse_albedo(a.albedo);
  if (!albedo) return albedo.error();
  o.albedo = *albedo;
  if (!probe::parse_shading_mode(a.mode, &o.mode)) return usage("--mode must be brute, median-cut or sh");
  o.size_px = a.size_px;
  o.light_count = a.count;
  o.brute_width = 256;  // 0.1 % mean, 0.4 % max from the full map (test_probe), 16x faster
  std::string why;
  if (!o.is_valid(&why)) return usage(why);
  if (a.gamma < 0) return usage("--gamma must be >= 0 (0: automatic)");
  auto p = load(a.file, a.design_notes);
  if (!p) return p.error();
  const cv::Mat radiance = probe::render_diffuse_sphere(*p, o);
  const double gamma = a.gamma > 0 ? a.gamma : probe::auto_gamma(radiance);
  VDRIG_TRY(write_png(a.out, probe::tone_map_srgb8(radiance, gamma)));
  std::printf("wrote %s (%d x %d, %s, tone-mapping gamma %.4g)\n", a.out.c_str(), o.size_px, o.size_px,
              probe::to_string(o.mode), gamma);
  return Status::ok();
}

// ---- vdrig probe fuse ----------------------------------------------------------------------------------------------

// Comma-separated numbers, exactly `count` of them.
Result<std::vector<double>> parse_numbers(const std::string& text, size_t count, const std::string& what) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      size_t used = 0;
      v.push_back(std::stod(item, &used));
      if (used != item.size()) return usage(what + ": '" + item + "' is not a number in " + text);
    } catch (const std::exception&) {
      return usage(what + ": '" + item + "' is not a number in " + text);
    }
  }
  if (v.size() != count)
    return usage(what + " needs " + std::to_string(count) + " comma-separated numbers, got " + text);
  return v;
}

struct FuseArgs {
  std::vector<std::string> probes;  // FILE or FILE:X,Y,Z (mm)
  std::string room, at, out = "fused.exr", render;
  int height = 0;
  double angular_exponent = probe::FusionOptions{}.angular_exponent;
  double resolution_exponent = probe::FusionOptions{}.resolution_exponent;
  double min_cosine = probe::FusionOptions{}.min_cosine;
  bool design_notes = false;
  RenderArgs sphere;  // --albedo, --mode, --count, --size, --gamma for --render
};

Status run_fuse(const FuseArgs& a) {
  probe::FusionOptions o;
  o.height = a.height;
  o.angular_exponent = a.angular_exponent;
  o.resolution_exponent = a.resolution_exponent;
  o.min_cosine = a.min_cosine;
  std::string why;
  if (!o.is_valid(&why)) return usage(why);
  auto room = parse_numbers(a.room, 6, "--room");
  if (!room) return room.error();
  const probe::ProxyBox box{Vec3d((*room)[0], (*room)[1], (*room)[2]), Vec3d((*room)[3], (*room)[4], (*room)[5])};
  if (!box.is_valid(&why)) return usage("--room: " + why);
  auto at = parse_numbers(a.at, 3, "--at");
  if (!at) return at.error();
  const Vec3d position((*at)[0], (*at)[1], (*at)[2]);

  std::vector<probe::Probe> probes;
  for (const std::string& spec : a.probes) {
    // FILE:X,Y,Z sets the probe's position; a bare FILE keeps the position stored in it (save_probe's attributes).
    std::string file = spec;
    std::optional<Vec3d> pos;
    if (const size_t colon = spec.rfind(':'); colon != std::string::npos) {
      auto xyz = parse_numbers(spec.substr(colon + 1), 3, "probe position in " + spec);
      if (xyz) {
        file = spec.substr(0, colon);
        pos = Vec3d((*xyz)[0], (*xyz)[1], (*xyz)[2]);
      }
    }
    auto p = load(file, a.design_notes);
    if (!p) return p.error();
    if (pos) p->position_mm = *pos;
    std::printf("probe %s: %d x %d at %.1f, %.1f, %.1f mm, depth %s\n", file.c_str(), p->width(), p->height(),
                p->position_mm.x(), p->position_mm.y(), p->position_mm.z(), p->has_depth() ? "yes" : "none");
    probes.push_back(std::move(p.value()));
  }
  probe::FusionStats stats;
  auto fused = probe::fuse(probes, position, box, o, &stats);
  if (!fused) return fused.error();
  std::printf("fused at %.1f, %.1f, %.1f mm: %d x %d; weight shares", position.x(), position.y(), position.z(),
              fused->width(), fused->height());
  for (double s : stats.weight_share) std::printf(" %.3f", s);
  std::printf("; %d pixels (%.4f sr) seen by no probe\n", stats.uncovered_pixels, stats.uncovered_sr);
  VDRIG_TRY(probe::save_probe(a.out, *fused));
  std::printf("wrote %s\n", a.out.c_str());
  if (a.render.empty()) return Status::ok();

  // A diffuse sphere at the new position, lit by the fused map (same options as `vdrig probe render`).
  probe::SphereRenderOptions r;
  auto albedo = parse_albedo(a.sphere.albedo);
  if (!albedo) return albedo.error();
  r.albedo = *albedo;
  if (!probe::parse_shading_mode(a.sphere.mode, &r.mode)) return usage("--mode must be brute, median-cut or sh");
  r.size_px = a.sphere.size_px;
  r.light_count = a.sphere.count;
  r.brute_width = 256;
  if (!r.is_valid(&why)) return usage(why);
  if (a.sphere.gamma < 0) return usage("--gamma must be >= 0 (0: automatic)");
  const cv::Mat radiance = probe::render_diffuse_sphere(*fused, r);
  const double gamma = a.sphere.gamma > 0 ? a.sphere.gamma : probe::auto_gamma(radiance);
  VDRIG_TRY(write_png(a.render, probe::tone_map_srgb8(radiance, gamma)));
  std::printf("wrote %s (%d x %d, %s, tone-mapping gamma %.4g)\n", a.render.c_str(), r.size_px, r.size_px,
              probe::to_string(r.mode), gamma);
  return Status::ok();
}

const CommandRegistrar registrar([](CLI::App& root) {
  auto* cmd_probe = root.add_subcommand("probe", "light probes: info, median-cut lights, SH irradiance, render, fuse");
  cmd_probe->require_subcommand(1);
  auto add_file = [](CLI::App* cmd, std::string& file, bool& design_notes) {
    cmd->add_option("file", file, "equirectangular OpenEXR probe (2:1, row 0 up)")->required();
    cmd->add_flag("--design-notes-azimuth", design_notes,
                  "the file's columns already run with vdrig's azimuth (default: panorama / Blender layout)");
  };
  {
    auto* cmd = cmd_probe->add_subcommand("info", "size, total power, brightest direction");
    struct Args {
      std::string file;
      bool design_notes = false;
    };
    auto a = std::make_shared<Args>();
    add_file(cmd, a->file, a->design_notes);
    cmd->callback([a] { finish(run_info(a->file, a->design_notes)); });
  }
  {
    auto* cmd = cmd_probe->add_subcommand("lights", "median-cut directional lights as JSON");
    struct Args {
      std::string file, out = "lights.json";
      int count = 64;
      bool design_notes = false;
    };
    auto a = std::make_shared<Args>();
    add_file(cmd, a->file, a->design_notes);
    cmd->add_option("--count", a->count, "number of lights, a power of two")->capture_default_str();
    cmd->add_option("--out", a->out, "JSON to write")->capture_default_str();
    cmd->callback([a] { finish(run_lights(a->file, a->design_notes, a->count, a->out)); });
  }
  {
    auto* cmd = cmd_probe->add_subcommand("irradiance", "9 SH radiance coefficients per channel as JSON");
    struct Args {
      std::string file, out = "sh9.json";
      bool design_notes = false;
    };
    auto a = std::make_shared<Args>();
    add_file(cmd, a->file, a->design_notes);
    cmd->add_option("--out", a->out, "JSON to write")->capture_default_str();
    cmd->callback([a] { finish(run_irradiance(a->file, a->design_notes, a->out)); });
  }
  {
    auto* cmd = cmd_probe->add_subcommand("render", "a diffuse sphere lit by the probe, tone mapped to PNG");
    auto a = std::make_shared<RenderArgs>();
    add_file(cmd, a->file, a->design_notes);
    cmd->add_option("--albedo", a->albedo, "R,G,B in [0, 1]")->capture_default_str();
    cmd->add_option("--mode", a->mode, "brute | median-cut | sh")
        ->capture_default_str()
        ->check(CLI::IsMember({"brute", "median-cut", "sh"}));
    cmd->add_option("--count", a->count, "median-cut lights (power of two)")->capture_default_str();
    cmd->add_option("--size", a->size_px, "image side, pixels")->capture_default_str();
    cmd->add_option("--gamma", a->gamma, "tone mapping y = 1 - exp(-gamma x); 0: mean lit pixel -> 0.5")
        ->capture_default_str();
    cmd->add_option("--out", a->out, "PNG to write")->capture_default_str();
    cmd->callback([a] { finish(run_render(*a)); });
  }
  {
    auto* cmd = cmd_probe->add_subcommand("fuse", "fuse probes on a box proxy (the room) at a new position");
    auto a = std::make_shared<FuseArgs>();
    cmd->add_option("probes", a->probes, "FILE:X,Y,Z (probe position, mm) or FILE (position stored in the file)")
        ->required();
    cmd->add_option("--room", a->room, "XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX: the box proxy, mm")->required();
    cmd->add_option("--at", a->at, "X,Y,Z: where to fuse, mm (inside the room)")->required();
    cmd->add_option("--out", a->out, "fused probe (OpenEXR, vdrig layout, depth in Z)")->capture_default_str();
    cmd->add_option("--height", a->height, "rows of the fused map; 0: the probes'")->capture_default_str();
    cmd->add_option("--angular-exponent", a->angular_exponent, "weight ((1 + w.w_i) / 2)^p (0: off)")
        ->capture_default_str();
    cmd->add_option("--resolution-exponent", a->resolution_exponent, "weight min(1, density ratio)^q (0: off)")
        ->capture_default_str();
    cmd->add_option("--min-cosine", a->min_cosine, "drop a probe where w.w_i is below this")->capture_default_str();
    cmd->add_flag("--design-notes-azimuth", a->design_notes,
                  "the files' columns already run with vdrig's azimuth (default: panorama / Blender layout)");
    cmd->add_option("--render", a->render, "also render a diffuse sphere lit by the fused probe to this PNG");
    cmd->add_option("--albedo", a->sphere.albedo, "sphere albedo R,G,B in [0, 1]")->capture_default_str();
    cmd->add_option("--mode", a->sphere.mode, "sphere shading: brute | median-cut | sh")
        ->capture_default_str()
        ->check(CLI::IsMember({"brute", "median-cut", "sh"}));
    cmd->add_option("--count", a->sphere.count, "median-cut lights (power of two)")->capture_default_str();
    cmd->add_option("--size", a->sphere.size_px, "sphere image side, pixels")->capture_default_str();
    cmd->add_option("--gamma", a->sphere.gamma, "tone mapping y = 1 - exp(-gamma x); 0: mean lit pixel -> 0.5")
        ->capture_default_str();
    cmd->callback([a] { finish(run_fuse(*a)); });
  }
});

}  // namespace
}  // namespace vdrig::app
