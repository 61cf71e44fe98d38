// Writes the seed corpora of the fuzz targets with the project's own writers (Session, write_obsmap_file,
// ParameterMap::write, save_probe, room_to_json, path_to_json, sim_rig_config) into OUT/<target>/: `fuzz_make_corpus
// fuzz/corpus`. Each seed is a small valid input (a few hundred bytes to a few KB), so the fuzzers start inside the
// formats.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>

#include "vdrig/capture/session.hpp"
#include "vdrig/fitting/harmonic_model.hpp"
#include "vdrig/fitting/obsmap_file.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/fitting/phong_model.hpp"
#include "vdrig/probe/object_path.hpp"
#include "vdrig/probe/probe.hpp"
#include "vdrig/probe/probe_json.hpp"
#include "vdrig/sim/sim_rig.hpp"

using namespace vdrig;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

void check(const Status& s) {
  if (!s) {
    std::fprintf(stderr, "fuzz_make_corpus: %s\n", s.describe().c_str());
    std::exit(1);
  }
}

void write_text(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

void copy_into(const fs::path& from, const fs::path& to) {
  fs::create_directories(to.parent_path());
  fs::copy_file(from, to, fs::copy_options::overwrite_existing);
}

/// A two-view session with one committed view and an event: its manifest and journal.
void session_seeds(const fs::path& out, const fs::path& scratch) {
  const fs::path dir = scratch / "session";
  capture::Manifest manifest;
  manifest.rig_config = sim::sim_rig_config({{"camera", {{"width", 8}, {"height", 6}}}});
  manifest.scheme = "latlong:2";
  manifest.bracket = "fixed:0.01,0.04";
  manifest.exposures_s = {0.01, 0.04};
  manifest.views = {capture::PlannedView{0, Vec3d::UnitZ(), {0.0, 0.0}},
                    capture::PlannedView{1, Vec3d(0.5, 0.0, 0.8660254), {0.0, 0.5235988}}};
  manifest.extra = {{"route", {{"order", "nearest"}}}};
  auto session = capture::Session::create(dir, manifest);
  check(session.status());
  Frame frame;
  frame.image = cv::Mat(6, 8, CV_8UC3, cv::Scalar(10, 20, 30));
  frame.bits = 8;
  frame.sequence = 1;
  for (int b = 0; b < 2; ++b) {
    frame.exposure_s = manifest.exposures_s[b];
    check(session->append_frame(0, b, frame, false).status());
  }
  check(session->mark_view_complete(0, 2));
  check(session->append_event({{"event", "paused"}}));
  copy_into(dir / "journal.jsonl", out / "journal" / "one_view_and_event.jsonl");
  copy_into(dir / "manifest.json", out / "manifest" / "two_views.json");
  // An old journal (view_complete without a frame count) and a torn last line.
  write_text(out / "journal" / "old_marker_torn.jsonl",
             "{\"type\":\"view_complete\",\"view\":1}\n{\"type\":\"frame\",\"view\":0,\"bra");
}

void rig_config_seeds(const fs::path& out) {
  const fs::path d = out / "rig_config";
  write_text(d / "sim_default.json", sim::sim_rig_config().dump());
  write_text(d / "sim_full.json",
             sim::sim_rig_config({{"scene", "patchwork"},
                                  {"distance_mm", 2500},
                                  {"surface_offset_mm", {0, 0, 10}},
                                  {"samples_per_axis", 2},
                                  {"time_scale", 0},
                                  {"seed", 7},
                                  {"camera",
                                   {{"width", 64},
                                    {"height", 48},
                                    {"fx", 80},
                                    {"bits", 12},
                                    {"response", "linear"},
                                    {"full_well_e", 20000},
                                    {"read_noise_e", 3}}},
                                  {"stage", {{"pan_min_deg", -180}, {"pan_max_deg", 180}, {"speed_deg_s", 20}}},
                                  {"faults", {{"move_timeout_at", {3}}, {"drop_frame_at", {2, 5}}}}})
                 .dump());
  const json axis = {{"unit", 1}, {"counts_per_degree", 100}, {"min_deg", -90}, {"max_deg", 90}};
  json tilt = axis;
  tilt["unit"] = 2;
  write_text(
      d / "modbus_tcp.json",
      json{{"stage", {{"backend", "modbus-tcp"}, {"host", "192.0.2.1"}, {"port", 502}, {"pan", axis}, {"tilt", tilt}}},
           {"camera", {{"backend", "v4l2"}, {"device", "/dev/video0"}, {"width", 640}, {"height", 480}}}}
          .dump());
  write_text(d / "modbus_rtu.json", json{{"stage",
                                          {{"backend", "modbus-rtu"},
                                           {"device", "/dev/ttyUSB0"},
                                           {"baud", 115200},
                                           {"parity", "E"},
                                           {"word_order", "low-first"},
                                           {"pan", axis},
                                           {"tilt", tilt}}},
                                         {"camera", {{"backend", "usb-ptp"}, {"vendor_id", "04a9"}}}}
                                        .dump());
  const json stepdir_axis = {
      {"step_line", 1}, {"dir_line", 2}, {"limit_line", 3}, {"steps_per_degree", 44.4}, {"home_direction", "negative"}};
  write_text(d / "gpio_stepdir.json",
             json{{"stage",
                   {{"backend", "gpio-stepdir"}, {"chip", "gpiochip0"}, {"pan", stepdir_axis}, {"tilt", stepdir_axis}}},
                  {"camera", {{"backend", "sim"}}},
                  {"light", {{"backend", "sim"}}}}
                 .dump());
  // Every top-level key a config may have: a stated geometry, a named lock, the shared "sim" section.
  json top_level = sim::sim_rig_config({{"scene", "patchwork"}});
  top_level["geometry"] = {{"distance_mm", 2500}, {"pan_zero_deg", 1.5}, {"source", "tape measure"}};
  top_level["lock"] = "bench-1";
  write_text(d / "top_level.json", top_level.dump());
}

void vdobs_seeds(const fs::path& out) {
  fitting::ObservationMapSpec spec;
  spec.texels_s = 3;
  spec.texels_t = 2;
  fitting::ObservationMap map(spec, 2);
  for (int t = 0; t < 2; ++t)
    for (int s = 0; s < 3; ++s)
      for (int v = 0; v < 2; ++v)
        map.set(s, t, v, Eigen::Vector3f(0.1f * s, 0.2f, 0.3f * v), Eigen::Vector3f(0, 0.6f, 0.8f), v == 0 ? 1 : 0);
  fitting::ObsFileOptions options;
  options.tile_size = 2;
  fs::create_directories(out / "vdobs");
  check(fitting::write_obsmap_file(map, out / "vdobs" / "zstd_3x2_2views.vdobs", options));
  options.compression = fitting::ObsCompression::kNone;
  check(fitting::write_obsmap_file(map, out / "vdobs" / "raw_3x2_2views.vdobs", options));
}

void parameter_map_seeds(const fs::path& out) {
  fs::create_directories(out / "parameter_map");
  auto phong = fitting::parse_model("phong:1");
  check(phong.status());
  fitting::ParameterMap p(*phong, 2, 2, 100.0, 100.0);
  fitting::PhongParams params;
  params.kd = Vec3d(0.2, 0.3, 0.4);
  params.lobes = {fitting::PhongLobe{Vec3d(0.5, 0.5, 0.5), Vec3d::UnitZ(), 20.0}};
  fitting::set_phong_texel(p, 1, 1, params);
  check(p.write(out / "parameter_map" / "phong1_2x2.exr", ExrPixelType::kHalf));
  auto sh = fitting::parse_model("sh-ls:2");
  check(sh.status());
  fitting::ParameterMap q(*sh, 2, 1, 50.0, 25.0);
  fitting::set_harmonic_coefficients(q, 0, 0, Eigen::MatrixXd::Constant(4, 3, 0.25));
  check(q.write(out / "parameter_map" / "sh2_2x1.exr", ExrPixelType::kHalf));
}

void probe_seeds(const fs::path& out) {
  fs::create_directories(out / "probe_exr");
  probe::Probe p = probe::make_probe(2);
  p.radiance.setTo(cv::Scalar(1.0, 0.5, 0.25));
  check(probe::save_probe(out / "probe_exr" / "4x2.exr", p));
  p.depth_mm = cv::Mat(2, 4, CV_32FC1, cv::Scalar(1500.0f));
  p.position_mm = Vec3d(10, 20, 30);
  check(probe::save_probe(out / "probe_exr" / "4x2_depth.exr", p));
}

/// Rooms for `vdrig probe animate` (room_to_json): several probes with and without positions, a single probe, a
/// thin room with negative and fractional coordinates, and names with folders, spaces and non-ASCII characters.
void probe_room_seeds(const fs::path& out) {
  const fs::path d = out / "probe_room";
  probe::RoomDocument room;
  room.room = probe::ProxyBox{Vec3d(-2000, -1500, 0), Vec3d(2000, 1500, 2600)};
  room.probes = {{"a.exr", true, Vec3d(-1000, -700, 1200)},
                 {"b.exr", true, Vec3d(1000, 700, 1200)},
                 {"sub/c.exr", false, Vec3d::Zero()},
                 {"/abs/d.exr", true, Vec3d(0, 0, 2500.5)}};
  write_text(d / "four_probes.json", probe::room_to_json(room));
  room.probes = {{"only.exr", false, Vec3d::Zero()}};
  write_text(d / "one_probe.json", probe::room_to_json(room));
  room.room = probe::ProxyBox{Vec3d(-0.5, -1e-3, -250.25), Vec3d(0.5, 1e-3, 1e6)};
  room.probes = {{"with space.exr", true, Vec3d(0, 0, 0)}, {"\xc3\xa9t\xc3\xa9.exr", true, Vec3d(-0.25, 0, 1e5)}};
  write_text(d / "thin_room.json", probe::room_to_json(room));
}

/// Object paths (path_to_json): one key, a walk of several keys inside fusion's test room, and keys with fractional
/// and negative times.
void probe_path_seeds(const fs::path& out) {
  const fs::path d = out / "probe_path";
  probe::ObjectPath path;
  path.keys = {{0, Vec3d(0, 0, 1000)}};
  write_text(d / "one_key.json", probe::path_to_json(path));
  path.keys = {{0, Vec3d(-1500, -1000, 800)},
               {1.5, Vec3d(0, 0, 1200)},
               {3, Vec3d(1500, 1000, 1200)},
               {4.25, Vec3d(1800, -1300, 2400)}};
  write_text(d / "walk.json", probe::path_to_json(path));
  path.keys = {{-2.5, Vec3d(0.125, -0.5, 300)}, {-1e-3, Vec3d(-1899.5, 1399, 2499)}, {1e4, Vec3d(0, 0, 101)}};
  write_text(d / "odd_times.json", probe::path_to_json(path));
}

void daemon_seeds(const fs::path& out) {
  const fs::path d = out / "daemon_request";
  write_text(d / "status.txt", "{\"id\":1,\"cmd\":\"status\"}\n");
  write_text(d / "start_pause_list.txt",
             "{\"id\":\"a\",\"cmd\":\"start\",\"session\":\"s1\",\"scheme\":\"latlong:2\",\"bracket\":\"fixed:0.01\"}\n"
             "{\"id\":2,\"cmd\":\"pause\"}\n{\"id\":3,\"cmd\":\"list-sessions\"}\n"
             "{\"id\":4,\"cmd\":\"resume\",\"session\":\"s1\"}\n{\"id\":5,\"cmd\":\"abort\"}\n");
  write_text(d / "move_home.txt",
             "{\"cmd\":\"move\",\"pan_deg\":10,\"tilt_deg\":20}\n{\"cmd\":\"home\"}\n{\"cmd\":\"subscribe\"}\n");
  write_text(d / "start_scene_rig.txt", "{\"cmd\":\"start\",\"session\":\"s2\",\"scene\":\"patchwork\",\"rig\":" +
                                            sim::sim_rig_config({{"camera", {{"width", 16}, {"height", 12}}}}).dump() +
                                            "}\n");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: fuzz_make_corpus OUT (e.g. fuzz/corpus)\n");
    return 2;
  }
  const fs::path out = argv[1];
  const fs::path scratch = fs::temp_directory_path() / ("vdrig_make_corpus_" + std::to_string(::getpid()));
  fs::remove_all(scratch);
  session_seeds(out, scratch);
  rig_config_seeds(out);
  vdobs_seeds(out);
  parameter_map_seeds(out);
  probe_seeds(out);
  probe_room_seeds(out);
  probe_path_seeds(out);
  daemon_seeds(out);
  fs::remove_all(scratch);
  return 0;
}
