// `vdrig probe info|lights|irradiance|render FILE`: inspect an equirectangular HDR light probe, extract median-cut
// lights as JSON, write its irradiance map (or SH-9 coefficients as JSON), and render a diffuse sphere lit by it
// (probe/, docs/probe.md). `vdrig probe cube IN --size N|--height H --out OUT`: lat-long <-> cube strip.
// `vdrig probe fuse A.exr:X,Y,Z B.exr:X,Y,Z ... --room ... --at X,Y,Z`: fuse probes on a box proxy at a new position.
// `vdrig probe animate ROOM.json --path path.json --out frames/`: spheres moving along a path, lit per frame by soft
// lights of the probe fused on the GPU at their position (probe_gl), as PNG frames (and an MP4 with ffmpeg).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "commands.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/probe/animation.hpp"
#include "vdrig/probe/cube_map.hpp"
#include "vdrig/probe/fusion.hpp"
#include "vdrig/probe/irradiance_map.hpp"
#include "vdrig/probe/median_cut.hpp"
#include "vdrig/probe/object_path.hpp"
#include "vdrig/probe/path_lights.hpp"
#include "vdrig/probe/probe.hpp"
#include "vdrig/probe/probe_json.hpp"
#include "vdrig/probe/sh_irradiance.hpp"
#include "vdrig/probe/shading.hpp"
#include "vdrig/probe/soft_lights.hpp"
#include "vdrig/probe/video.hpp"
#include "vdrig/probe_gl/probe_animation.hpp"

namespace vdrig::app {
namespace {

Error usage(const std::string& m) { return make_error(ErrorCode::kInvalidArgument, m); }

Result<probe::Probe> load(const std::string& file, bool as_design_notes) {
  probe::LoadOptions o;
  o.azimuth = as_design_notes ? probe::FileAzimuth::kDesignNotes : probe::FileAzimuth::kPanorama;
  return probe::load_probe(file, o);
}

Status write_text(const std::string& out, const std::string& text) {
  VDRIG_TRY(write_file_atomic(out, text));
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
  const probe::LightsDocument lights{file, probe::median_cut(*p, count)};
  std::printf("%zu median-cut lights, total power %.6g (luminance)\n", lights.lights.size(),
              probe::luminance(probe::total_power(*p)));
  return write_text(out, probe::lights_to_json(lights));
}

// `vdrig probe irradiance`: an irradiance map in the input's layout (lat-long panorama or vdrig's, or a cube strip),
// or with --json the SH-9 coefficients.
struct IrradianceArgs {
  std::string file, method = "exact", out;
  int width = 128;
  bool json = false, design_notes = false;
};

Status run_irradiance(const IrradianceArgs& a) {
  auto method = probe::parse_irradiance_method(a.method);
  if (!method) return usage("--method: " + method.error().message);
  if (a.json) {
    if (method->method != probe::IrradianceMethod::kSh9)
      return usage("--json writes SH-9 coefficients: use --method sh9");
    auto p = load(a.file, a.design_notes);
    if (!p) return p.error();
    return write_text(a.out.empty() ? "sh9.json" : a.out, probe::sh9_to_json({a.file, probe::project_sh9(*p)}));
  }
  const std::string out = a.out.empty() ? "irradiance.exr" : a.out;
  probe::LoadOptions o;
  o.azimuth = a.design_notes ? probe::FileAzimuth::kDesignNotes : probe::FileAzimuth::kPanorama;
  probe::FileAzimuth layout = probe::FileAzimuth::kDesignNotes;
  auto p = probe::load_probe(a.file, o, &layout);
  if (!p && p.error().code == ErrorCode::kInvalidArgument) {
    // Not 2:1: a cube strip (6 N x N) gives a cube of --width texels a side.
    auto cube = probe::load_cube_map(a.file);
    if (!cube)
      return make_error(ErrorCode::kInvalidArgument, p.error().message + "; nor a cube map: " + cube.error().message);
    if (a.width < 1) return usage("--width (cube face size) must be >= 1");
    const probe::CubeMap e = probe::irradiance_cube(probe::IrradianceModel::build(*cube, *method), a.width);
    VDRIG_TRY(probe::save_cube_map(out, e));
    std::printf("wrote %s (irradiance cube 6 x %d x %d, %s)\n", out.c_str(), a.width, a.width, a.method.c_str());
    return Status::ok();
  }
  if (!p) return p.error();
  if (a.width < 2 || a.width % 2 != 0) return usage("--width must be even and >= 2");
  probe::Probe e = probe::irradiance_latlong(probe::IrradianceModel::build(*p, *method), a.width);
  e.position_mm = p->position_mm;
  e.rotation = p->rotation;
  VDRIG_TRY(probe::save_probe(out, e, layout));
  std::printf("wrote %s (irradiance %d x %d, %s, %s layout)\n", out.c_str(), e.width(), e.height(), a.method.c_str(),
              layout == probe::FileAzimuth::kPanorama ? "panorama" : "design-notes");
  return Status::ok();
}

// `vdrig probe cube`: a lat-long probe to a cube strip, or a cube strip (6 N x N) back to a lat-long probe.
struct CubeArgs {
  std::string file, out;
  int size = 128, height = 0;
  bool design_notes = false;
};

Status run_cube(const CubeArgs& a) {
  auto p = load(a.file, a.design_notes);
  if (p) {
    if (a.size < 1) return usage("--size must be >= 1");
    VDRIG_TRY(probe::save_cube_map(a.out, probe::latlong_to_cube(*p, a.size)));
    std::printf("wrote %s (cube 6 x %d x %d)\n", a.out.c_str(), a.size, a.size);
    return Status::ok();
  }
  if (p.error().code != ErrorCode::kInvalidArgument) return p.error();
  auto cube = probe::load_cube_map(a.file);
  if (!cube)
    return make_error(ErrorCode::kInvalidArgument, p.error().message + "; nor a cube map: " + cube.error().message);
  const int height = a.height > 0 ? a.height : 2 * cube->size;
  VDRIG_TRY(probe::save_probe(a.out, probe::cube_to_latlong(*cube, height)));
  std::printf("wrote %s (lat-long %d x %d, vdrig layout)\n", a.out.c_str(), 2 * height, height);
  return Status::ok();
}

Result<probe::Rgb> parse_albedo(const std::string& text) {
  std::stringstream ss(text);
  probe::Rgb a;
  char comma1 = 0, comma2 = 0;
  if (!(ss >> a.x() >> comma1 >> a.y() >> comma2 >> a.z()) || comma1 != ',' || comma2 != ',' || !ss.eof())
    return usage("--albedo must be R,G,B (each in [0, 1]), got " + text);
  return a;
}

// The diffuse sphere's options, shared by `render` and `fuse --render`.
struct SphereArgs {
  std::string albedo = "0.8,0.8,0.8", mode = "sh";
  int size_px = 256, count = 256;
  double gamma = 0;
};

Result<probe::SphereRenderOptions> sphere_options(const SphereArgs& a) {
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
  return o;
}

Status write_sphere(const probe::Probe& p, const probe::SphereRenderOptions& o, double gamma, const std::string& out) {
  auto image = probe::render_sphere_image(p, o, gamma);
  if (!image) return image.error();
  VDRIG_TRY(write_png(out, image->bgr8));
  std::printf("wrote %s (%d x %d, %s, tone-mapping gamma %.4g)\n", out.c_str(), o.size_px, o.size_px,
              probe::to_string(o.mode), image->gamma);
  return Status::ok();
}

struct RenderArgs {
  std::string file, out = "sphere.png";
  bool design_notes = false;
  SphereArgs sphere;
};

Status run_render(const RenderArgs& a) {
  auto o = sphere_options(a.sphere);
  if (!o) return o.error();
  auto p = load(a.file, a.design_notes);
  if (!p) return p.error();
  return write_sphere(*p, *o, a.sphere.gamma, a.out);
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

// FILE:X,Y,Z sets the probe's position; a bare FILE keeps the position stored in it (save_probe's attributes).
Result<std::vector<probe::Probe>> load_probes(const std::vector<std::string>& specs, bool design_notes) {
  std::vector<probe::Probe> probes;
  for (const std::string& spec : specs) {
    std::string file = spec;
    std::optional<Vec3d> pos;
    if (const size_t colon = spec.rfind(':'); colon != std::string::npos) {
      auto xyz = parse_numbers(spec.substr(colon + 1), 3, "probe position in " + spec);
      if (xyz) {
        file = spec.substr(0, colon);
        pos = Vec3d((*xyz)[0], (*xyz)[1], (*xyz)[2]);
      }
    }
    auto p = load(file, design_notes);
    if (!p) return p.error();
    if (pos) p->position_mm = *pos;
    std::printf("probe %s: %d x %d at %.1f, %.1f, %.1f mm, depth %s\n", file.c_str(), p->width(), p->height(),
                p->position_mm.x(), p->position_mm.y(), p->position_mm.z(), p->has_depth() ? "yes" : "none");
    probes.push_back(std::move(p.value()));
  }
  return probes;
}

Result<probe::ProxyBox> parse_room(const std::string& text) {
  auto room = parse_numbers(text, 6, "--room");
  if (!room) return room.error();
  const probe::ProxyBox box{Vec3d((*room)[0], (*room)[1], (*room)[2]), Vec3d((*room)[3], (*room)[4], (*room)[5])};
  std::string why;
  if (!box.is_valid(&why)) return usage("--room: " + why);
  return box;
}

struct FuseArgs {
  std::vector<std::string> probes;  // FILE or FILE:X,Y,Z (mm)
  std::string room, at, out = "fused.exr", render;
  int height = 0;
  double angular_exponent = probe::FusionOptions{}.angular_exponent;
  double resolution_exponent = probe::FusionOptions{}.resolution_exponent;
  double min_cosine = probe::FusionOptions{}.min_cosine;
  bool design_notes = false;
  SphereArgs sphere;  // --albedo, --mode, --count, --size, --gamma for --render
};

Status run_fuse(const FuseArgs& a) {
  probe::FusionOptions o;
  o.height = a.height;
  o.angular_exponent = a.angular_exponent;
  o.resolution_exponent = a.resolution_exponent;
  o.min_cosine = a.min_cosine;
  std::string why;
  if (!o.is_valid(&why)) return usage(why);
  std::optional<probe::SphereRenderOptions> sphere;
  if (!a.render.empty()) {
    auto r = sphere_options(a.sphere);
    if (!r) return r.error();
    sphere = *r;
  }
  auto room = parse_room(a.room);
  if (!room) return room.error();
  const probe::ProxyBox& box = *room;
  auto at = parse_numbers(a.at, 3, "--at");
  if (!at) return at.error();
  const Vec3d position((*at)[0], (*at)[1], (*at)[2]);

  auto probes = load_probes(a.probes, a.design_notes);
  if (!probes) return probes.error();
  probe::FusionStats stats;
  auto fused = probe::fuse(*probes, position, box, o, &stats);
  if (!fused) return fused.error();
  std::printf("fused at %.1f, %.1f, %.1f mm: %d x %d; weight shares", position.x(), position.y(), position.z(),
              fused->width(), fused->height());
  for (double s : stats.weight_share) std::printf(" %.3f", s);
  std::printf("; %d pixels (%.4f sr) seen by no probe\n", stats.uncovered_pixels, stats.uncovered_sr);
  VDRIG_TRY(probe::save_probe(a.out, *fused));
  std::printf("wrote %s\n", a.out.c_str());
  if (!sphere) return Status::ok();
  // A diffuse sphere at the new position, lit by the fused map (same options as `vdrig probe render`).
  return write_sphere(*fused, *sphere, a.sphere.gamma, a.render);
}

// ---- vdrig probe path ----------------------------------------------------------------------------------------------

struct PathArgs {
  std::vector<std::string> probes;
  std::string room, path, method = "soft:64", out = "path_lights";
  int frames = 300, height = 0;
  double margin_mm = 0;
  bool design_notes = false;
};

// Lights for a moving object: the probe fused at each frame's position on the path, turned into lights; per frame
// DIR/frame_NNNN.lights.json (and .sh9.json for methods with an SH-9 part).
Status run_path(const PathArgs& a) {
  auto method = probe::parse_irradiance_method(a.method);
  if (!method) return usage("--method: " + method.error().message);
  if (method->method == probe::IrradianceMethod::kExact) return usage("--method exact has no lights to write");
  if (a.frames < 1) return usage("--frames must be >= 1");
  auto room = parse_room(a.room);
  if (!room) return room.error();
  std::ifstream in(a.path);
  if (!in) return make_error(ErrorCode::kNotFound, "path file " + a.path + " cannot be read");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto path = probe::path_from_json(text);
  if (!path) return path.error();
  VDRIG_TRY(probe::validate_path(*path, *room, a.margin_mm));
  auto probes = load_probes(a.probes, a.design_notes);
  if (!probes) return probes.error();
  probe::FusionOptions o;
  o.height = a.height;
  VDRIG_TRY(probe::write_path_lights(*probes, *room, probe::sample_path(*path, a.frames), *method, o, a.out));
  std::printf("wrote %d frames of %s lights to %s\n", a.frames, a.method.c_str(), a.out.c_str());
  return Status::ok();
}

// ---- vdrig probe animate ------------------------------------------------------------------------------------------

struct AnimateArgs {
  std::string room, path, out = "frames", method = "soft:64", camera, look_at;
  int frames = 120, width = 640, height = 360, cube = 128, shrink = 8, shadow_lights = 4, samples = 2;
  double fov_deg = 50, radius_mm = 150, gamma = 0, fps = 30;
  bool design_notes = false, no_mp4 = false;
};

// Argument checks that name the options; the rest (room, probes, path, camera, OpenGL) is checked by
// render_probe_animation before the first frame is written.
Status run_animate(const AnimateArgs& a) {
  auto method = probe::parse_irradiance_method(a.method);
  if (!method) return usage("--method: " + method.error().message);
  if (method->method != probe::IrradianceMethod::kSoft)
    return usage("--method must be soft:N (the temporally stable lights), got " + a.method);
  if (a.frames < 1) return usage("--frames must be >= 1");
  if (a.cube < 1 || a.shrink < 1 || a.cube % a.shrink != 0)
    return usage("--cube must be a positive multiple of --shrink, got " + std::to_string(a.cube) + " and " +
                 std::to_string(a.shrink));
  if (!(a.fps > 0)) return usage("--fps must be > 0");
  if (a.gamma < 0 || !std::isfinite(a.gamma)) return usage("--gamma must be >= 0 (0: automatic from frame 0)");
  probe_gl::ProbeAnimationSettings settings;
  settings.room_file = a.room;
  settings.path_file = a.path;
  settings.out_dir = a.out;
  settings.frames = a.frames;
  settings.soft_lights = method->light_count;
  settings.width = a.width;
  settings.height = a.height;
  settings.cube_size = a.cube;
  settings.shrink = a.shrink;
  settings.sphere_radius_mm = a.radius_mm;
  settings.shadow_lights = a.shadow_lights;
  settings.samples_per_axis = a.samples;
  settings.fov_deg = a.fov_deg;
  settings.gamma = a.gamma;
  settings.design_notes = a.design_notes;
  if (!a.camera.empty()) {
    auto v = parse_numbers(a.camera, 3, "--camera");
    if (!v) return v.error();
    settings.camera_mm = Vec3d((*v)[0], (*v)[1], (*v)[2]);
  }
  if (!a.look_at.empty()) {
    auto v = parse_numbers(a.look_at, 3, "--look-at");
    if (!v) return v.error();
    settings.look_at_mm = Vec3d((*v)[0], (*v)[1], (*v)[2]);
  }
  auto done = probe_gl::render_probe_animation(settings);
  if (!done) return done.error();
  std::printf(
      "wrote %d frames (%d x %d) to %s: per frame GPU fusion + read-back %.1f ms, soft:%d lights %.1f ms, "
      "render + PNG %.1f ms\n",
      done->frames, a.width, a.height, a.out.c_str(), done->fuse_ms, method->light_count, done->lights_ms,
      done->render_ms);
  if (a.no_mp4) return Status::ok();
  auto mp4 = probe::encode_frames_mp4(a.out, a.fps);
  if (!mp4 && mp4.error().code == ErrorCode::kNotFound) {
    std::printf("ffmpeg not on PATH: no MP4 (the PNG frames are complete)\n");
    return Status::ok();
  }
  if (!mp4) return mp4.error();
  std::printf("wrote %s (%.6g frames/s)\n", mp4->c_str(), a.fps);
  return Status::ok();
}

const CommandRegistrar registrar([](CLI::App& root) {
  auto* cmd_probe =
      root.add_subcommand("probe", "light probes: info, lights, irradiance, cube, render, fuse, path, animate");
  cmd_probe->require_subcommand(1);
  auto add_sphere_options = [](CLI::App* cmd, SphereArgs& sphere) {
    cmd->add_option("--albedo", sphere.albedo, "sphere albedo R,G,B in [0, 1]")->capture_default_str();
    cmd->add_option("--mode", sphere.mode, "sphere shading: brute | median-cut | sh")
        ->capture_default_str()
        ->check(CLI::IsMember({"brute", "median-cut", "sh"}));
    cmd->add_option("--count", sphere.count, "median-cut lights (power of two)")->capture_default_str();
    cmd->add_option("--size", sphere.size_px, "sphere image side, pixels")->capture_default_str();
    cmd->add_option("--gamma", sphere.gamma, "tone mapping y = 1 - exp(-gamma x); 0: mean lit pixel -> 0.5")
        ->capture_default_str();
  };
  auto add_file = [](CLI::App* cmd, std::string& file, bool& design_notes) {
    cmd->add_option("file", file, "equirectangular OpenEXR probe (2:1, row 0 up)")->required();
    cmd->add_flag("--design-notes-azimuth", design_notes,
                  "the file's columns already run with vdrig's azimuth (default: panorama / Blender layout)");
  };
  // Source probes placed in a room, for `fuse` and `path`.
  auto add_probes_and_room = [](CLI::App* cmd, std::vector<std::string>& probes, std::string& room,
                                bool& design_notes) {
    cmd->add_option("probes", probes, "FILE:X,Y,Z (probe position, mm) or FILE (position stored in the file)")
        ->required();
    cmd->add_option("--room", room, "XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX: the box proxy, mm")->required();
    cmd->add_flag("--design-notes-azimuth", design_notes,
                  "the files' columns already run with vdrig's azimuth (default: panorama / Blender layout)");
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
    auto* cmd = cmd_probe->add_subcommand("irradiance", "irradiance map (OpenEXR, the input's layout) or SH-9 JSON");
    auto a = std::make_shared<IrradianceArgs>();
    add_file(cmd, a->file, a->design_notes);
    cmd->add_option("--method", a->method, "exact | sh9 | mediancut:N | hybrid:N | soft:N")->capture_default_str();
    cmd->add_option("--width", a->width, "output width (height width / 2); for a cube input, the face size")
        ->capture_default_str();
    cmd->add_flag("--json", a->json, "with --method sh9: write the 9 SH radiance coefficients as JSON instead");
    cmd->add_option("--out", a->out, "file to write (default irradiance.exr, or sh9.json with --json)");
    cmd->callback([a] { finish(run_irradiance(*a)); });
  }
  {
    auto* cmd =
        cmd_probe->add_subcommand("cube", "lat-long probe -> cube strip (6 N x N), or a cube strip -> lat-long");
    auto a = std::make_shared<CubeArgs>();
    add_file(cmd, a->file, a->design_notes);
    cmd->add_option("--size", a->size, "cube face size (lat-long input)")->capture_default_str();
    cmd->add_option("--height", a->height, "lat-long rows (cube input); 0: twice the face size")->capture_default_str();
    cmd->add_option("--out", a->out, "OpenEXR to write")->required();
    cmd->callback([a] { finish(run_cube(*a)); });
  }
  {
    auto* cmd = cmd_probe->add_subcommand("render", "a diffuse sphere lit by the probe, tone mapped to PNG");
    auto a = std::make_shared<RenderArgs>();
    add_file(cmd, a->file, a->design_notes);
    add_sphere_options(cmd, a->sphere);
    cmd->add_option("--out", a->out, "PNG to write")->capture_default_str();
    cmd->callback([a] { finish(run_render(*a)); });
  }
  {
    auto* cmd = cmd_probe->add_subcommand("fuse", "fuse probes on a box proxy (the room) at a new position");
    auto a = std::make_shared<FuseArgs>();
    add_probes_and_room(cmd, a->probes, a->room, a->design_notes);
    cmd->add_option("--at", a->at, "X,Y,Z: where to fuse, mm (inside the room)")->required();
    cmd->add_option("--out", a->out, "fused probe (OpenEXR, vdrig layout, depth in Z)")->capture_default_str();
    cmd->add_option("--height", a->height, "rows of the fused map; 0: the probes'")->capture_default_str();
    cmd->add_option("--angular-exponent", a->angular_exponent, "weight ((1 + w.w_i) / 2)^p (0: off)")
        ->capture_default_str();
    cmd->add_option("--resolution-exponent", a->resolution_exponent, "weight min(1, density ratio)^q (0: off)")
        ->capture_default_str();
    cmd->add_option("--min-cosine", a->min_cosine, "drop a probe where w.w_i is below this")->capture_default_str();
    cmd->add_option("--render", a->render, "also render a diffuse sphere lit by the fused probe to this PNG");
    add_sphere_options(cmd, a->sphere);
    cmd->callback([a] { finish(run_fuse(*a)); });
  }
  {
    auto* cmd = cmd_probe->add_subcommand("path", "lights per frame for an object moving along a path in the room");
    auto a = std::make_shared<PathArgs>();
    add_probes_and_room(cmd, a->probes, a->room, a->design_notes);
    cmd->add_option("--path", a->path, "path JSON (vdrig.probe.path: keys of time_s and position_mm)")->required();
    cmd->add_option("--frames", a->frames, "frames, evenly spaced in time over the path")->capture_default_str();
    cmd->add_option("--method", a->method, "soft:N | mediancut:N | hybrid:N | sh9")->capture_default_str();
    cmd->add_option("--margin", a->margin_mm, "keys must stay this far from every wall, mm (the object's radius)")
        ->capture_default_str();
    cmd->add_option("--height", a->height, "rows of the fused maps; 0: the probes'")->capture_default_str();
    cmd->add_option("--out", a->out, "folder for frame_NNNN.lights.json / .sh9.json")->capture_default_str();
    cmd->callback([a] { finish(run_path(*a)); });
  }
  {
    auto* cmd = cmd_probe->add_subcommand(
        "animate", "spheres moving along a path, lit by the probes fused on the GPU: PNG frames (+ MP4)");
    auto a = std::make_shared<AnimateArgs>();
    cmd->add_option("room", a->room, "room JSON (vdrig.probe.room: the box and the probes placed in it)")->required();
    cmd->add_option("--path", a->path, "path JSON (vdrig.probe.path: keys of time_s and position_mm)")->required();
    cmd->add_option("--out", a->out, "folder for frame_NNNN.png, frames.json and animation.mp4")->capture_default_str();
    cmd->add_option("--frames", a->frames, "frames, evenly spaced in time over the path")->capture_default_str();
    cmd->add_option("--method", a->method, "lights: soft:N")->capture_default_str();
    cmd->add_option("--width", a->width, "frame width, pixels")->capture_default_str();
    cmd->add_option("--height", a->height, "frame height, pixels")->capture_default_str();
    cmd->add_option("--cube", a->cube, "face size of the fused cube")->capture_default_str();
    cmd->add_option("--shrink", a->shrink, "the cube is shrunk by this factor for the lights")->capture_default_str();
    cmd->add_option("--radius", a->radius_mm, "sphere radius, mm (also the path's margin from the walls)")
        ->capture_default_str();
    cmd->add_option("--shadow-lights", a->shadow_lights, "strongest lights casting shadows on the ground")
        ->capture_default_str();
    cmd->add_option("--samples", a->samples, "antialiasing rays per pixel and axis")->capture_default_str();
    cmd->add_option("--camera", a->camera, "X,Y,Z camera position, mm (default: from -y, 35 deg up, all in view)");
    cmd->add_option("--look-at", a->look_at, "X,Y,Z point the camera looks at, mm");
    cmd->add_option("--fov", a->fov_deg, "horizontal field of view, degrees")->capture_default_str();
    cmd->add_option("--gamma", a->gamma, "tone mapping y = 1 - exp(-gamma x); 0: from frame 0, then fixed")
        ->capture_default_str();
    cmd->add_option("--fps", a->fps, "frame rate of the MP4")->capture_default_str();
    cmd->add_flag("--no-mp4", a->no_mp4, "do not run ffmpeg even when it is on PATH");
    cmd->add_flag("--design-notes-azimuth", a->design_notes,
                  "probe files without vdrig attributes already run with vdrig's azimuth (default: panorama)");
    cmd->callback([a] { finish(run_animate(*a)); });
  }
});

}  // namespace
}  // namespace vdrig::app
