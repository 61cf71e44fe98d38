#include "vdrig/sim/sim_rig.hpp"

#include <chrono>
#include <cmath>
#include <set>
#include <thread>

#include "vdrig/core/log.hpp"

namespace vdrig::sim {
namespace {

using nlohmann::json;

Status reject_unknown(const json& j, const std::set<std::string>& known, const std::string& where) {
  for (const auto& [k, v] : j.items())
    if (!known.count(k)) return make_error(ErrorCode::kInvalidArgument, where + ": unknown key \"" + k + "\"");
  return Status::ok();
}

}  // namespace

double trapezoid_time_s(double distance, double max_speed, double accel) {
  distance = std::abs(distance);
  if (distance == 0.0) return 0.0;
  const double ramp = max_speed * max_speed / accel;  // distance to accelerate and decelerate fully
  if (distance <= ramp) return 2.0 * std::sqrt(distance / accel);
  return 2.0 * max_speed / accel + (distance - ramp) / max_speed;
}

SimConfig::SimConfig() {
  stage.pan = {deg_to_rad(-360), deg_to_rad(360), deg_to_rad(30), deg_to_rad(60), false};
  stage.tilt = {deg_to_rad(-5), deg_to_rad(85), deg_to_rad(30), deg_to_rad(60), false};
}

Result<SimConfig> SimConfig::from_json(const json& j) {
  SimConfig c;
  try {
    VDRIG_TRY(reject_unknown(j, {"scene", "distance_mm", "samples_per_axis", "time_scale", "seed", "camera", "stage"},
                             "sim"));
    c.scene = j.value("scene", c.scene);
    c.geometry.camera_distance_mm = j.value("distance_mm", c.geometry.camera_distance_mm);
    c.samples_per_axis = j.value("samples_per_axis", c.samples_per_axis);
    c.time_scale = j.value("time_scale", c.time_scale);
    c.sensor.seed = j.value("seed", c.sensor.seed);
    if (j.contains("camera")) {
      const json& cam = j["camera"];
      VDRIG_TRY(reject_unknown(cam, {"width", "height", "fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "bits",
                                     "response", "full_well_e", "read_noise_e", "vignetting"},
                               "sim.camera"));
      CameraModel& m = c.camera;
      m.width = cam.value("width", m.width);
      m.height = cam.value("height", m.height);
      m.fx = cam.value("fx", m.fx);
      m.fy = cam.value("fy", m.fy);
      m.cx = cam.value("cx", (m.width - 1) / 2.0);
      m.cy = cam.value("cy", (m.height - 1) / 2.0);
      m.k1 = cam.value("k1", m.k1);
      m.k2 = cam.value("k2", m.k2);
      m.p1 = cam.value("p1", m.p1);
      m.p2 = cam.value("p2", m.p2);
      m.k3 = cam.value("k3", m.k3);
      const int bits = cam.value("bits", 8);
      if (bits < 8 || bits > 16) return make_error(ErrorCode::kInvalidArgument, "sim.camera.bits must be 8..16");
      const std::string response = cam.value("response", std::string("s-curve"));
      if (response == "s-curve")
        c.sensor.response = ResponseCurve::s_curve(bits);
      else if (response == "linear")
        c.sensor.response = ResponseCurve::linear(bits);
      else
        return make_error(ErrorCode::kInvalidArgument, "sim.camera.response must be \"s-curve\" or \"linear\"");
      c.sensor.full_well_e = cam.value("full_well_e", 0.0);
      c.sensor.read_noise_e = cam.value("read_noise_e", 0.0);
      c.sensor.vignetting = cam.value("vignetting", 0.0);
    }
    if (j.contains("stage")) {
      const json& st = j["stage"];
      VDRIG_TRY(reject_unknown(st, {"pan_min_deg", "pan_max_deg", "tilt_min_deg", "tilt_max_deg", "speed_deg_s",
                                    "accel_deg_s2"},
                               "sim.stage"));
      auto deg = [&](const char* k, double def_rad) { return deg_to_rad(st.value(k, rad_to_deg(def_rad))); };
      c.stage.pan.min_rad = deg("pan_min_deg", c.stage.pan.min_rad);
      c.stage.pan.max_rad = deg("pan_max_deg", c.stage.pan.max_rad);
      c.stage.tilt.min_rad = deg("tilt_min_deg", c.stage.tilt.min_rad);
      c.stage.tilt.max_rad = deg("tilt_max_deg", c.stage.tilt.max_rad);
      c.stage.pan.max_speed_rad_s = c.stage.tilt.max_speed_rad_s = deg("speed_deg_s", c.stage.pan.max_speed_rad_s);
      c.stage.pan.accel_rad_s2 = c.stage.tilt.accel_rad_s2 = deg("accel_deg_s2", c.stage.pan.accel_rad_s2);
    }
  } catch (const json::exception& e) {
    return make_error(ErrorCode::kInvalidArgument, std::string("sim config: ") + e.what());
  }
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
  if (!sensor.is_valid(why)) return false;
  if (samples_per_axis < 1 || samples_per_axis > 8) return fail("samples_per_axis must be 1..8");
  if (time_scale < 0) return fail("time_scale must be >= 0");
  if (!(geometry.camera_distance_mm > 0)) return fail("distance_mm must be positive");
  if (stage.pan.min_rad > stage.pan.max_rad || stage.tilt.min_rad > stage.tilt.max_rad) return fail("empty axis range");
  if (stage.pan.max_speed_rad_s <= 0 || stage.pan.accel_rad_s2 <= 0) return fail("speed and acceleration must be > 0");
  return true;
}

namespace {

class SimStage final : public rig::PanTiltStage {
 public:
  explicit SimStage(std::shared_ptr<SimWorld> world) : world_(std::move(world)) {}
  std::string backend() const override { return "sim"; }
  rig::StageSpec spec() const override { return world_->config.stage; }

  Status home() override {
    PanTilt zero;
    VDRIG_TRY(move_to(zero));
    std::lock_guard lock(world_->mutex);
    world_->homed = true;
    return Status::ok();
  }

  Status move_to(const PanTilt& target) override {
    const rig::StageSpec& s = world_->config.stage;
    if (target.pan_rad < s.pan.min_rad || target.pan_rad > s.pan.max_rad || target.tilt_rad < s.tilt.min_rad ||
        target.tilt_rad > s.tilt.max_rad)
      return make_error(ErrorCode::kInvalidArgument, "sim stage: target outside the axis limits");
    PanTilt from;
    {
      std::lock_guard lock(world_->mutex);
      from = world_->position;
    }
    const double t = std::max(trapezoid_time_s(target.pan_rad - from.pan_rad, s.pan.max_speed_rad_s, s.pan.accel_rad_s2),
                              trapezoid_time_s(target.tilt_rad - from.tilt_rad, s.tilt.max_speed_rad_s,
                                               s.tilt.accel_rad_s2));
    if (world_->config.time_scale > 0)
      std::this_thread::sleep_for(std::chrono::duration<double>(t * world_->config.time_scale));
    std::lock_guard lock(world_->mutex);
    world_->position = target;
    return Status::ok();
  }

  Result<PanTilt> position() override {
    std::lock_guard lock(world_->mutex);
    return world_->position;
  }

  Status stop() override { return Status::ok(); }

 private:
  std::shared_ptr<SimWorld> world_;
};

class SimCamera final : public rig::Camera {
 public:
  explicit SimCamera(std::shared_ptr<SimWorld> world) : world_(std::move(world)) {}
  std::string backend() const override { return "sim"; }

  Result<rig::CameraInfo> info() override {
    const auto& c = world_->config;
    return rig::CameraInfo{"vdrig simulated camera", c.camera.width, c.camera.height, c.sensor.response.bits(), 1e-6,
                           60.0, false};
  }

  Status set_exposure(double exposure_s, double gain) override {
    if (!(exposure_s > 0) || !(gain > 0))
      return make_error(ErrorCode::kInvalidArgument, "sim camera: exposure and gain must be positive");
    std::lock_guard lock(world_->mutex);
    world_->exposure_s = exposure_s;
    world_->gain = gain;
    return Status::ok();
  }

  Result<Frame> capture() override {  // NOLINT(readability-function-size)
    ViewPose pose;
    Frame frame;
    {
      std::lock_guard lock(world_->mutex);
      pose = world_->pose();
      frame.exposure_s = world_->exposure_s;
      frame.gain = world_->gain;
      frame.measured = world_->position;
      frame.commanded = world_->position;
      frame.sequence = world_->frame_sequence++;
    }
    const auto& c = world_->config;
    frame.timestamp_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                             std::chrono::system_clock::now().time_since_epoch())
                             .count();
    frame.bits = c.sensor.response.bits();
    // A bracket photographs the same pose several times: render the radiance once per pose and light state.
    const bool light_on = world_->light_on;
    if (cached_.empty() || cached_position_.pan_rad != frame.measured.pan_rad ||
        cached_position_.tilt_rad != frame.measured.tilt_rad || cached_light_on_ != light_on) {
      Scene scene = world_->scene;
      if (!light_on) scene.lights.clear();
      cached_ = render_radiance(scene, c.camera, pose, c.samples_per_axis);
      cached_position_ = frame.measured;
      cached_light_on_ = light_on;
    }
    frame.image = expose(cached_, frame.exposure_s, frame.gain, c.sensor, frame.sequence);
    return frame;
  }

 private:
  std::shared_ptr<SimWorld> world_;
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
  ctx.shared["sim.world"] = world;
  log::get("sim")->debug("simulated rig: scene {}, camera {}x{}", world->scene.name, world->config.camera.width,
                         world->config.camera.height);
  return world;
}

template <typename Device, typename Impl>
rig::Factory<Device> factory() {
  return [](const json&, rig::RigContext& ctx) -> Result<std::unique_ptr<Device>> {
    auto world = shared_world(ctx);
    if (!world) return world.error();
    return std::unique_ptr<Device>(std::make_unique<Impl>(world.value()));
  };
}

}  // namespace

void register_backends(rig::BackendRegistry& registry) {
  registry.add_stage("sim", factory<rig::PanTiltStage, SimStage>());
  registry.add_camera("sim", factory<rig::Camera, SimCamera>());
  registry.add_light("sim", factory<rig::Light, SimLight>());
}

json sim_rig_config(const json& sim_section) {
  return {{"stage", {{"backend", "sim"}}},
          {"camera", {{"backend", "sim"}}},
          {"light", {{"backend", "sim"}}},
          {"sim", sim_section}};
}

}  // namespace vdrig::sim
