#include "vdrig/sim/sim_rig.hpp"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <thread>

#include "blender_camera.hpp"
#include "vdrig/core/file_read.hpp"
#include "vdrig/core/file_write.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/core/settings.hpp"
#include "vdrig/core/splitmix64.hpp"
#include "vdrig/rig/geometry_config.hpp"
#include "vdrig/rig/lamp.hpp"
#include "vdrig/rig/motion.hpp"

namespace vdrig::sim {

using nlohmann::json;

namespace {

uint64_t mix64(uint64_t h, uint64_t v) {  // splitmix64's step over h ^ v: every input bit reaches every output bit
  return splitmix64_finalise((h ^ v) + kSplitMix64Increment);
}

uint64_t bits_of(double x) { return std::bit_cast<uint64_t>(x == 0.0 ? 0.0 : x); }  // -0 and +0 are one position

}  // namespace

uint64_t SimWorld::noise_key(uint64_t sequence) const {
  if (!config.noise_by_shot) return sequence;
  // expose() mixes the sensor seed in itself; the key is what is shot. A bracket's frames differ by their exposure.
  uint64_t h = mix64(0, bits_of(position.pan_rad));
  h = mix64(h, bits_of(position.tilt_rad));
  h = mix64(h, bits_of(exposure_s));
  h = mix64(h, bits_of(gain));
  return mix64(h, light_on ? 1 : 0);
}

bool SimFaults::any() const {
  return !move_timeout_at.empty() || !drive_error_at.empty() || !drop_frame_at.empty() ||
         !disconnect_camera_at.empty() || slow_write_ms > 0;
}

SimConfig::SimConfig() {
  stage.pan = {deg_to_rad(-360), deg_to_rad(360), deg_to_rad(30), deg_to_rad(60), false};
  stage.tilt = {deg_to_rad(-5), deg_to_rad(85), deg_to_rad(30), deg_to_rad(60), false};
}

namespace {

constexpr long long kIntMin = std::numeric_limits<int>::min();
constexpr long long kIntMax = std::numeric_limits<int>::max();

int read_int(Settings& s, const char* key, int fallback) {
  return static_cast<int>(s.integer(key, fallback, kIntMin, kIntMax));
}

void read_faults(Settings& parent, const json& section, SimFaults& f) {
  Settings s(section, "faults");
  s.reject_unknown({"move_timeout_at", "drive_error_at", "drop_frame_at", "disconnect_camera_at", "disconnect_calls",
                    "slow_write_ms"});
  f.move_timeout_at = s.unsigned_list("move_timeout_at", {});
  f.drive_error_at = s.unsigned_list("drive_error_at", {});
  f.drop_frame_at = s.unsigned_list("drop_frame_at", {});
  f.disconnect_camera_at = s.unsigned_list("disconnect_camera_at", {});
  f.disconnect_calls = s.unsigned_integer("disconnect_calls", f.disconnect_calls);
  f.slow_write_ms = s.number("slow_write_ms", f.slow_write_ms);
  parent.absorb(s);
}

void read_camera(Settings& parent, const json& section, SimConfig& c) {
  Settings s(section, "camera");
  s.reject_unknown({"width", "height", "fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "bits", "response",
                    "full_well_e", "read_noise_e", "vignetting", "noise_seed"});
  CameraModel& m = c.camera;
  m.width = static_cast<int>(s.integer("width", m.width, 1, SimConfig::kMaxCameraSide));
  m.height = static_cast<int>(s.integer("height", m.height, 1, SimConfig::kMaxCameraSide));
  m.fx = s.number("fx", m.fx);
  m.fy = s.number("fy", m.fy);
  m.cx = s.number("cx", (m.width - 1) / 2.0);
  m.cy = s.number("cy", (m.height - 1) / 2.0);
  m.k1 = s.number("k1", m.k1);
  m.k2 = s.number("k2", m.k2);
  m.p1 = s.number("p1", m.p1);
  m.p2 = s.number("p2", m.p2);
  m.k3 = s.number("k3", m.k3);
  const int bits = static_cast<int>(s.integer("bits", 8, 8, 16));
  const std::string response = s.string("response", "s-curve", {"s-curve", "linear"});
  c.sensor.response = response == "linear" ? ResponseCurve::linear(bits) : ResponseCurve::s_curve(bits);
  // A simulated camera has noise unless told otherwise: fits are judged on what a real capture gives them (shot
  // noise of a small sensor's well, a few electrons of read noise), not on exact radiance (docs/sim.md).
  c.sensor.full_well_e = s.number("full_well_e", kDefaultFullWellE);
  c.sensor.read_noise_e = s.number("read_noise_e", c.sensor.full_well_e > 0 ? kDefaultReadNoiseE : 0.0);
  c.sensor.vignetting = s.number("vignetting", 0.0);
  c.noise_by_shot = s.string("noise_seed", "sequence", {"sequence", "shot"}) == "shot";
  parent.absorb(s);
}

void read_stage(Settings& parent, const json& section, rig::StageSpec& stage) {
  Settings s(section, "stage");
  s.reject_unknown({"pan_min_deg", "pan_max_deg", "tilt_min_deg", "tilt_max_deg", "speed_deg_s", "accel_deg_s2"});
  auto deg = [&](const char* k, double def_rad) { return deg_to_rad(s.number(k, rad_to_deg(def_rad))); };
  stage.pan.min_rad = deg("pan_min_deg", stage.pan.min_rad);
  stage.pan.max_rad = deg("pan_max_deg", stage.pan.max_rad);
  stage.tilt.min_rad = deg("tilt_min_deg", stage.tilt.min_rad);
  stage.tilt.max_rad = deg("tilt_max_deg", stage.tilt.max_rad);
  stage.pan.max_speed_rad_s = stage.tilt.max_speed_rad_s = deg("speed_deg_s", stage.pan.max_speed_rad_s);
  stage.pan.accel_rad_s2 = stage.tilt.accel_rad_s2 = deg("accel_deg_s2", stage.pan.accel_rad_s2);
  parent.absorb(s);
}

}  // namespace

Result<SimConfig> SimConfig::from_json(const json& j) {
  SimConfig c;
  Settings s(j, "sim");
  s.reject_unknown({"scene", "distance_mm", "surface_offset_mm", "pan_zero_deg", "tilt_zero_deg", "pan_axis_tilt_deg",
                    "samples_per_axis", "time_scale", "seed", "state_file", "camera", "stage", "faults"});
  c.scene = s.string("scene", c.scene);
  c.geometry.camera_distance_mm = s.number("distance_mm", c.geometry.camera_distance_mm);
  const Vec3d& o = c.geometry.surface_offset_mm;
  const std::vector<double> offset = s.number_list("surface_offset_mm", {o.x(), o.y(), o.z()}, 3);
  c.geometry.surface_offset_mm = Vec3d(offset[0], offset[1], offset[2]);
  // An imperfect rig (rig/kinematics.hpp): the stage reports encoder readings, the platform moves by the true angles.
  c.geometry.pan_zero_rad = deg_to_rad(s.number("pan_zero_deg", 0.0));
  c.geometry.tilt_zero_rad = deg_to_rad(s.number("tilt_zero_deg", 0.0));
  const std::vector<double> axis_tilt = s.number_list("pan_axis_tilt_deg", {0.0, 0.0}, 2);
  c.geometry.pan_axis_tilt_x_rad = deg_to_rad(axis_tilt[0]);
  c.geometry.pan_axis_tilt_y_rad = deg_to_rad(axis_tilt[1]);
  c.samples_per_axis = read_int(s, "samples_per_axis", c.samples_per_axis);
  c.time_scale = s.number("time_scale", c.time_scale);
  c.state_file = s.string("state_file", c.state_file);
  c.sensor.seed = s.unsigned_integer("seed", c.sensor.seed);
  if (s.has("faults")) read_faults(s, s.object("faults", true), c.faults);
  if (s.has("camera")) read_camera(s, s.object("camera", true), c);
  if (s.has("stage")) read_stage(s, s.object("stage", true), c.stage);
  if (!s.is_valid(nullptr)) return s.error();
  std::string why;
  if (!c.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "sim config: " + why);
  return c;
}

bool SimConfig::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!camera.is_valid(why)) return false;
  if (camera.width > kMaxCameraSide || camera.height > kMaxCameraSide)
    return fail("camera width and height must be at most " + std::to_string(kMaxCameraSide) + " px");
  if (!sensor.is_valid(why)) return false;
  if (samples_per_axis < 1 || samples_per_axis > 8) return fail("samples_per_axis must be 1..8");
  if (time_scale < 0) return fail("time_scale must be >= 0");
  if (!rig::geometry_is_valid(geometry, why)) return false;  // the hidden truth obeys the stated range
  if (!(faults.slow_write_ms >= 0)) return fail("faults.slow_write_ms must be >= 0");
  for (const auto* list :
       {&faults.move_timeout_at, &faults.drive_error_at, &faults.drop_frame_at, &faults.disconnect_camera_at})
    for (uint64_t n : *list)
      if (n == 0) return fail("fault call numbers count from 1");
  if (stage.pan.min_rad > stage.pan.max_rad || stage.tilt.min_rad > stage.tilt.max_rad) return fail("empty axis range");
  if (stage.pan.max_speed_rad_s <= 0 || stage.pan.accel_rad_s2 <= 0) return fail("speed and acceleration must be > 0");
  return true;
}

namespace {

bool contains(const std::vector<uint64_t>& list, uint64_t n) {
  return std::find(list.begin(), list.end(), n) != list.end();
}

void sleep_s(double s) {
  if (s > 0) std::this_thread::sleep_for(std::chrono::duration<double>(s));
}

/// The stage's position and homed flag in config.state_file (when set), as a real drive keeps them between processes.
Status save_state(SimWorld& world) {
  if (world.config.state_file.empty()) return Status::ok();
  json state;
  {
    std::lock_guard lock(world.mutex);
    state = {{"format", "vdrig.sim.stage_state"},
             {"pan_deg", rad_to_deg(world.position.pan_rad)},
             {"tilt_deg", rad_to_deg(world.position.tilt_rad)},
             {"homed", world.homed}};
  }
  const Status written = write_file_atomic(world.config.state_file, state.dump(2) + "\n");
  if (!written)
    return make_error(written.error().code, "sim stage: cannot keep its position in state_file " +
                                                world.config.state_file + ": " + written.error().message);
  return Status::ok();
}

/// Reads config.state_file into the world when the file exists (a missing file: the stage starts at 0, 0).
Status load_state(SimWorld& world) {
  std::error_code ec;
  if (world.config.state_file.empty() || !std::filesystem::exists(world.config.state_file, ec)) return Status::ok();
  auto state = read_json_file(world.config.state_file);
  const auto corrupt = [&](const std::string& why) {
    return make_error(ErrorCode::kCorrupt, "sim state_file " + world.config.state_file + ": " + why +
                                               " (delete it to start the stage at 0, 0)");
  };
  if (!state) return corrupt(state.error().message);
  if (!state->is_object() || state->value("format", "") != "vdrig.sim.stage_state" || !state->contains("pan_deg") ||
      !(*state)["pan_deg"].is_number() || !state->contains("tilt_deg") || !(*state)["tilt_deg"].is_number())
    return corrupt("not a simulated stage's state");
  world.position = {deg_to_rad((*state)["pan_deg"].get<double>()), deg_to_rad((*state)["tilt_deg"].get<double>())};
  world.homed = state->value("homed", false);
  return Status::ok();
}

class SimStage final : public rig::PanTiltStage {
 public:
  explicit SimStage(std::shared_ptr<SimWorld> world) : world_(std::move(world)) {}
  std::string backend() const override { return "sim"; }
  rig::StageSpec spec() const override { return world_->config.stage; }
  double wall_time_scale() const override { return world_->config.time_scale; }

  Status home() override {
    VDRIG_TRY(move(PanTilt{}, false));
    {
      std::lock_guard lock(world_->mutex);
      world_->homed = true;
    }
    return save_state(*world_);
  }

  Status move_to(const PanTilt& target) override { return move(target, true); }

  Result<PanTilt> position() override {
    std::lock_guard lock(world_->mutex);
    return world_->position;
  }

  Status stop() override {
    sleep_s(world_->config.faults.slow_write_ms / 1000.0);
    return Status::ok();
  }

 private:
  /// A move of both axes at once; `counted` moves are numbered for fault injection.
  Status move(const PanTilt& target, bool counted) {
    const SimConfig& c = world_->config;
    const rig::StageSpec& s = c.stage;
    sleep_s(c.faults.slow_write_ms / 1000.0);
    // Out-of-range targets are refused, never clamped: a clamped move would photograph the wrong direction.
    if (!(target.pan_rad >= s.pan.min_rad && target.pan_rad <= s.pan.max_rad && target.tilt_rad >= s.tilt.min_rad &&
          target.tilt_rad <= s.tilt.max_rad))
      return make_error(ErrorCode::kInvalidArgument,
                        "sim stage: target (" + std::to_string(rad_to_deg(target.pan_rad)) + ", " +
                            std::to_string(rad_to_deg(target.tilt_rad)) + ") deg outside the axis limits");
    PanTilt from;
    uint64_t call = 0;
    {
      std::lock_guard lock(world_->mutex);
      from = world_->position;
      if (counted) call = ++world_->move_calls;
    }
    if (counted && contains(c.faults.drive_error_at, call))
      return make_error(ErrorCode::kDevice,
                        "sim stage: drive alarm (injected fault, move " + std::to_string(call) + ")");
    const bool times_out = counted && contains(c.faults.move_timeout_at, call);
    PanTilt reached = target;
    if (times_out) reached = {(from.pan_rad + target.pan_rad) / 2.0, (from.tilt_rad + target.tilt_rad) / 2.0};
    const double t = rig::move_time_s(s, from, reached);
    sleep_s(t * c.time_scale);
    {
      std::lock_guard lock(world_->mutex);
      world_->position = reached;
      world_->motion_time_s += t;
    }
    VDRIG_TRY(save_state(*world_));
    if (times_out)
      return make_error(ErrorCode::kTimeout,
                        "sim stage: move did not finish in time (injected fault, move " + std::to_string(call) + ")");
    return Status::ok();
  }

  std::shared_ptr<SimWorld> world_;
};

class SimCamera final : public rig::Camera {
 public:
  /// `follow` (may be null): a stage other than the simulator's, whose reported position each capture renders.
  SimCamera(std::shared_ptr<SimWorld> world, rig::PanTiltStage* follow) : world_(std::move(world)), follow_(follow) {}
  std::string backend() const override { return "sim"; }

  Result<rig::CameraInfo> info() override {
    {
      std::lock_guard lock(world_->mutex);
      VDRIG_TRY(check_connected_locked());
    }
    const auto& c = world_->config;
    return rig::CameraInfo{
        "vdrig simulated camera", c.camera.width, c.camera.height, c.sensor.response.bits(), 1e-6, 60.0, false};
  }

  Status set_exposure(double exposure_s, double gain) override {
    sleep_s(world_->config.faults.slow_write_ms / 1000.0);
    if (!(exposure_s > 0) || !(gain > 0))
      return make_error(ErrorCode::kInvalidArgument, "sim camera: exposure and gain must be positive");
    std::lock_guard lock(world_->mutex);
    VDRIG_TRY(check_connected_locked());
    world_->exposure_s = exposure_s;
    world_->gain = gain;
    return Status::ok();
  }

  Result<Frame> capture() override {  // NOLINT(readability-function-size)
    ViewPose pose;
    Frame frame;
    bool light_on = true;
    uint64_t noise_key = 0;
    const auto& c = world_->config;
    if (follow_) {
      // A real stage with the simulated camera: the picture shows where that stage says it is.
      auto at = follow_->position();
      if (!at) return at.error();
      std::lock_guard lock(world_->mutex);
      world_->position = at.value();
    }
    {
      std::lock_guard lock(world_->mutex);
      const uint64_t call = ++world_->capture_calls;
      if (world_->disconnected_at_call == 0 && contains(c.faults.disconnect_camera_at, call))
        world_->disconnected_at_call = call;
      VDRIG_TRY(check_connected_locked());
      if (contains(c.faults.drop_frame_at, call)) {
        ++world_->frame_sequence;  // the sensor exposed it; it never arrived
        return make_error(ErrorCode::kTimeout,
                          "sim camera: frame did not arrive (injected fault, capture " + std::to_string(call) + ")");
      }
      pose = world_->pose();
      frame.exposure_s = world_->exposure_s;
      frame.gain = world_->gain;
      frame.measured = world_->position;
      frame.commanded = world_->position;
      frame.sequence = world_->frame_sequence++;
      noise_key = world_->noise_key(frame.sequence);
      light_on = world_->light_on;
      if (!world_->rays || !world_->rays->matches(c.camera, c.samples_per_axis))
        world_->rays = std::make_shared<const RayTable>(c.camera, c.samples_per_axis);
    }
    frame.timestamp_ns =
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
            .count();
    frame.bits = c.sensor.response.bits();
    // A bracket photographs the same pose several times: render the radiance once per pose and light state.
    if (cached_.empty() || cached_position_.pan_rad != frame.measured.pan_rad ||
        cached_position_.tilt_rad != frame.measured.tilt_rad || cached_light_on_ != light_on) {
      Scene scene = world_->scene;
      if (!light_on) {
        scene.lights.clear();
        scene.area_lights.clear();
      }
      cached_ = render_radiance(scene, *world_->rays, pose);
      cached_position_ = frame.measured;
      cached_light_on_ = light_on;
    }
    frame.image = expose(cached_, frame.exposure_s, frame.gain, c.sensor, noise_key);
    return frame;
  }

 private:
  /// kDisconnected while an injected disconnection lasts (counts the calls it refuses). Caller holds the mutex.
  Status check_connected_locked() {
    SimWorld& w = *world_;
    if (w.disconnected_at_call == 0) return Status::ok();
    const uint64_t limit = w.config.faults.disconnect_calls;
    if (limit > 0 && w.camera_calls_while_disconnected >= limit) {
      w.disconnected_at_call = 0;  // plugged back in
      w.camera_calls_while_disconnected = 0;
      return Status::ok();
    }
    ++w.camera_calls_while_disconnected;
    return make_error(ErrorCode::kDisconnected, "sim camera: camera went away (injected fault at capture " +
                                                    std::to_string(w.disconnected_at_call) + ")");
  }

  std::shared_ptr<SimWorld> world_;
  rig::PanTiltStage* follow_ = nullptr;
  cv::Mat cached_;
  PanTilt cached_position_;
  bool cached_light_on_ = true;
};

class SimLight final : public rig::Light {
 public:
  explicit SimLight(std::shared_ptr<SimWorld> world) : world_(std::move(world)) {}
  std::string backend() const override { return "sim"; }
  Status set_on(bool on) override {
    std::lock_guard lock(world_->mutex);
    world_->light_on = on;
    return Status::ok();
  }

 private:
  std::shared_ptr<SimWorld> world_;
};

/// The world shared by the sim devices of one rig, created by the first of them from the config's "sim" section.
Result<std::shared_ptr<SimWorld>> shared_world(rig::RigContext& ctx) {
  if (auto it = ctx.shared.find("sim.world"); it != ctx.shared.end())
    return std::static_pointer_cast<SimWorld>(it->second);
  auto config = SimConfig::from_json(ctx.config.value("sim", json::object()));
  if (!config) return config.error();
  auto scene = make_scene(config->scene);
  if (!scene) return scene.error();
  auto world = std::make_shared<SimWorld>();
  world->config = std::move(config.value());
  world->scene = std::move(scene.value());
  VDRIG_TRY(load_state(*world));
  ctx.shared["sim.world"] = world;
  log::get("sim")->debug("simulated rig: scene {}, camera {}x{}", world->scene.name, world->config.camera.width,
                         world->config.camera.height);
  if (world->config.faults.any()) log::get("sim")->info("simulated rig: fault injection is on");
  return world;
}

/// A simulated device's own section holds only "backend": everything the simulator reads is in the shared "sim"
/// section, so any other key there is a mistake (a stage setting meant for "sim"."stage", say).
Result<json> check_device_section(const std::string& kind, const json& section) {
  Settings s(section, kind + " sim", {"backend"});
  s.reject_unknown(std::vector<std::string>{});
  if (!s.is_valid(nullptr)) return s.error();
  return section;
}

template <typename Device, typename Impl>
rig::Factory<Device> factory(const std::string& kind) {
  return [kind](const json& section, rig::RigContext& ctx) -> Result<std::unique_ptr<Device>> {
    if (auto checked = check_device_section(kind, section); !checked) return checked.error();
    auto world = shared_world(ctx);
    if (!world) return world.error();
    return std::unique_ptr<Device>(std::make_unique<Impl>(world.value()));
  };
}

}  // namespace

rig::BackendSpec backend_spec(const std::string& kind) {
  return {{"sim"}, [kind](const json& section) { return check_device_section(kind, section); }};
}

void register_backends(rig::BackendRegistry& registry) {
  registry.add_section("sim", [](const json& section) -> Status {
    auto config = SimConfig::from_json(section);
    return config ? Status::ok() : Status(config.error());
  });
  registry.add_stage("sim", factory<rig::PanTiltStage, SimStage>("stage"), backend_spec("stage"));
  registry.add_camera(
      "sim",
      [](const json& section, rig::RigContext& ctx) -> Result<std::unique_ptr<rig::Camera>> {
        if (auto checked = check_device_section("camera", section); !checked) return checked.error();
        auto world = shared_world(ctx);
        if (!world) return world.error();
        // Paired with another backend's stage, the camera follows that stage (registry.cpp: "rig.stage").
        rig::PanTiltStage* follow = nullptr;
        if (auto it = ctx.shared.find("rig.stage"); it != ctx.shared.end()) {
          auto* stage = static_cast<rig::PanTiltStage*>(it->second.get());
          if (stage && stage->backend() != "sim") follow = stage;
        }
        return std::unique_ptr<rig::Camera>(std::make_unique<SimCamera>(world.value(), follow));
      },
      backend_spec("camera"));
  registry.add_light("sim", factory<rig::Light, SimLight>("light"), backend_spec("light"));
  register_blender_camera(registry, shared_world);  // the "blender" camera (docs/blender.md)
}

rig::BackendRegistry simulator_and_hardware_backends() {
  rig::BackendRegistry registry;
  register_backends(registry);
  rig::register_hardware_backends(registry);
  return registry;
}

json sim_rig_config(const json& sim_section) {
  json light = {{"backend", "sim"}};
  // The session records its light as a real rig's config states its measured lamp (rig/lamp.hpp): a scene lit by
  // one point light gives its position and intensity, which a BRDF fit then takes (docs/models.md, "The light").
  if (sim_section.is_object())
    if (auto scene = make_scene(sim_section.value("scene", "patchwork"));
        scene && scene->lights.size() == 1 && scene->area_lights.empty() && scene->ambient.isZero()) {
      // To a thousandth (of a mm; of the intensity's unit, ~1e-10 of it): the config is shown to people (vdrig report).
      const auto thousandths = [](const Vec3d& v) { return Vec3d((v * 1000.0).array().round() / 1000.0); };
      rig::LampPosition lamp;
      lamp.position_mm = thousandths(scene->lights.front().position_mm);
      lamp.intensity = thousandths(scene->lights.front().intensity);
      lamp.source = "the simulated scene " + scene->name + "'s point light";
      light.update(rig::lamp_keys(lamp));
    }
  return {{"stage", {{"backend", "sim"}}}, {"camera", {{"backend", "sim"}}}, {"light", light}, {"sim", sim_section}};
}

}  // namespace vdrig::sim
