// vdrig rig: bring-up of a real rig (docs/hardware.md). The work is in rig/bringup.hpp; this file parses arguments
// and prints.
#include <cstdio>

#include "commands.hpp"
#include "rig_backends.hpp"
#include "vdrig/capture/daemon.hpp"
#include "vdrig/capture/process_lock.hpp"
#include "vdrig/core/file_read.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/json_text.hpp"
#include "vdrig/rig/bringup.hpp"

namespace vdrig::app {
namespace {
using nlohmann::json;
constexpr double kRadPerDeg = 3.14159265358979323846 / 180.0;

struct RigArgs {
  std::string config;
  std::string runtime_dir;  // ignored: locks no longer live in a runtime folder (process_lock.hpp)
  bool self_test = false;
  double pan_deg = 0.0, tilt_deg = 0.0;
  double exposure_s = 0.01, gain = 1.0;
  std::string out;
};

Result<json> read_config(const std::string& file) {
  auto config = read_json_file(file);
  if (!config) return make_error(ErrorCode::kInvalidArgument, "cannot read rig config: " + config.error().message);
  return config;
}

/// A built rig and the lock that keeps another process (a capture, vdrigd) off it while we drive it.
struct OpenRig {
  std::optional<capture::ProcessLock> lock;
  rig::Rig rig;
  json config;
};

Result<OpenRig> open_rig(const RigArgs& a) {
  auto config = read_config(a.config);
  if (!config) return config.error();
  OpenRig open;
  open.config = config.value();
  auto lock = capture::lock_rig(config.value());
  if (!lock) return lock.error();
  open.lock = std::move(lock.value());
  auto rig = rig_backends().make_rig(config.value());
  if (!rig) return rig.error();
  open.rig = std::move(rig.value());
  return open;
}

Status devices() {
  for (const auto& kind : rig::list_devices()) {
    std::printf("%s:\n", kind.kind.c_str());
    if (!kind.note.empty())
      std::printf("  (not searched: %s)\n", kind.note.c_str());
    else if (kind.devices.empty())
      std::printf("  none found\n");
    for (const auto& d : kind.devices)
      std::printf("  %s%s%s\n", d.path.c_str(), d.summary.empty() ? "" : "  ", d.summary.c_str());
  }
  return Status::ok();
}

Status check(const RigArgs& a) {
  // Read as text here, not with read_config: a repeated key is one more problem to list with the others, not a
  // reason to stop before them.
  auto text = read_regular_file(a.config, kMaxJsonFileBytes);
  if (!text) return make_error(ErrorCode::kInvalidArgument, "cannot read rig config: " + text.error().message);
  auto parsed = parse_json_text(text.value(), a.config);
  if (!parsed) return make_error(ErrorCode::kInvalidArgument, "cannot read rig config: " + parsed.error().message);
  const json& config = parsed->value;
  auto report = rig::check_rig_config(config, rig_backends());
  report.problems.insert(report.problems.begin(), parsed->duplicate_keys.begin(), parsed->duplicate_keys.end());
  std::printf("effective settings:\n%s\n", report.effective.dump(2).c_str());
  if (!report.problems.empty()) {
    std::printf("%zu problem(s):\n", report.problems.size());
    for (const auto& p : report.problems) std::printf("  - %s\n", p.c_str());
    return make_error(ErrorCode::kInvalidArgument, a.config + ": the rig config is not valid");
  }
  std::printf("config valid\n");
  if (!a.self_test) return Status::ok();
  auto open = open_rig(a);
  if (!open) return open.error();
  std::printf("self-test:\n");
  const auto steps = rig::run_self_test(open->rig);
  bool passed = true;
  for (const auto& s : steps) {
    std::printf("  %s  %s: %s\n", s.passed ? "PASS" : "FAIL", s.name.c_str(), s.detail.c_str());
    passed = passed && s.passed;
  }
  std::printf("self-test %s\n", passed ? "passed" : "FAILED");
  std::fflush(stdout);
  return passed ? Status::ok() : make_error(ErrorCode::kDevice, "self-test failed");
}

Status print_position(const OpenRig& open) {
  auto p = open.rig.stage->position();
  if (!p) return p.error();
  std::printf("pan %.4f deg  tilt %.4f deg\n", p->pan_rad / kRadPerDeg, p->tilt_rad / kRadPerDeg);
  // A real drive keeps its position after the command; the simulated stage only with a state file (docs/sim.md).
  const json& sim = open.config.contains("sim") ? open.config["sim"] : json();
  const bool kept = sim.is_object() && sim.contains("state_file") && sim["state_file"].is_string() &&
                    !sim["state_file"].get<std::string>().empty();
  if (open.rig.stage->backend() == "sim" && !kept)
    std::printf(
        "(simulated stage: this position is not kept, the next command starts at 0, 0; set \"state_file\" in the "
        "rig config's \"sim\" section to keep it, docs/sim.md)\n");
  return Status::ok();
}

Status home(const RigArgs& a) {
  auto open = open_rig(a);
  if (!open) return open.error();
  VDRIG_TRY(open->rig.stage->home());
  return print_position(open.value());
}

Status move(const RigArgs& a) {
  auto open = open_rig(a);
  if (!open) return open.error();
  VDRIG_TRY(open->rig.stage->move_to({a.pan_deg * kRadPerDeg, a.tilt_deg * kRadPerDeg}));
  return print_position(open.value());
}

Status position(const RigArgs& a) {
  auto open = open_rig(a);
  if (!open) return open.error();
  return print_position(open.value());
}

Status shoot(const RigArgs& a) {
  if (a.out.empty()) return make_error(ErrorCode::kInvalidArgument, "--out F.png is required");
  auto open = open_rig(a);
  if (!open) return open.error();
  VDRIG_TRY(open->rig.camera->set_exposure(a.exposure_s, a.gain));
  auto frame = open->rig.camera->capture();
  if (!frame) return frame.error();
  VDRIG_TRY(write_png(a.out, frame->image));
  std::printf("%s: %dx%d, %d bit, exposure %.6g s, gain %.3g\n", a.out.c_str(), frame->image.cols, frame->image.rows,
              frame->bits, frame->exposure_s, frame->gain);
  return Status::ok();
}

CommandRegistrar reg([](CLI::App& root) {
  auto* rig = root.add_subcommand("rig", "bring-up of a real rig: devices, config check, self-test, manual moves");
  rig->require_subcommand(1);
  auto a = std::make_shared<RigArgs>();
  auto add_config = [a](CLI::App* cmd, bool positional) {
    if (positional)
      cmd->add_option("CONFIG", a->config, "rig config JSON file")->required();
    else
      cmd->add_option("--rig", a->config, "rig config JSON file")->required();
    cmd->add_option("--runtime-dir", a->runtime_dir,
                    "ignored, for older scripts: rigs are locked per device wherever the runtime folder is");
  };
  rig->add_subcommand("devices", "list cameras, serial ports and GPIO chips found on this machine")->callback([] {
    finish(devices());
  });
  auto* chk = rig->add_subcommand("check", "validate a rig config, print its effective settings; --self-test runs it");
  add_config(chk, true);
  chk->add_flag("--self-test", a->self_test, "home, small moves, a short bracket: a pass/fail report");
  chk->callback([a] { finish(check(*a)); });
  auto* hm = rig->add_subcommand("home", "home both axes");
  add_config(hm, false);
  hm->callback([a] { finish(home(*a)); });
  auto* mv = rig->add_subcommand("move", "move to an absolute pan/tilt (the stage must be homed)");
  add_config(mv, false);
  mv->add_option("--pan", a->pan_deg, "pan, degrees")->required();
  mv->add_option("--tilt", a->tilt_deg, "tilt, degrees")->required();
  mv->callback([a] { finish(move(*a)); });
  auto* pos = rig->add_subcommand("position", "print the position the stage reads back");
  add_config(pos, false);
  pos->callback([a] { finish(position(*a)); });
  auto* sh = rig->add_subcommand("shoot", "take one frame at a given exposure");
  add_config(sh, false);
  sh->add_option("--exposure", a->exposure_s, "exposure time, s")->required();
  sh->add_option("--gain", a->gain, "analogue gain")->capture_default_str();
  sh->add_option("--out", a->out, "PNG file to write")->required();
  sh->callback([a] { finish(shoot(*a)); });
});

}  // namespace
}  // namespace vdrig::app
