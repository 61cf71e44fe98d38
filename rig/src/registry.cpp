#include "vdrig/rig/registry.hpp"

#include "vdrig/core/log.hpp"

namespace vdrig::rig {
namespace {

template <typename Map>
std::vector<std::string> keys(const Map& m) {
  std::vector<std::string> out;
  for (const auto& [k, v] : m) out.push_back(k);
  return out;
}

std::string join(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s.empty() ? "(none)" : s;
}

template <typename Device>
Result<std::unique_ptr<Device>> build(const std::map<std::string, Factory<Device>>& factories, const char* kind,
                                      const nlohmann::json& section, RigContext& ctx) {
  if (!section.is_object() || !section.contains("backend") || !section["backend"].is_string())
    return make_error(ErrorCode::kInvalidArgument, std::string("rig config: \"") + kind +
                                                       "\" needs a \"backend\" name; known: " + join(keys(factories)));
  const std::string name = section["backend"].get<std::string>();
  const auto it = factories.find(name);
  if (it == factories.end())
    return make_error(ErrorCode::kInvalidArgument, std::string("rig config: unknown ") + kind + " backend \"" + name +
                                                       "\"; known: " + join(keys(factories)));
  log::get("rig")->debug("creating {} backend {}", kind, name);
  return it->second(section, ctx);
}

}  // namespace

void BackendRegistry::add_stage(const std::string& name, Factory<PanTiltStage> f) { stages_[name] = std::move(f); }
void BackendRegistry::add_camera(const std::string& name, Factory<Camera> f) { cameras_[name] = std::move(f); }
void BackendRegistry::add_light(const std::string& name, Factory<Light> f) { lights_[name] = std::move(f); }
std::vector<std::string> BackendRegistry::stage_backends() const { return keys(stages_); }
std::vector<std::string> BackendRegistry::camera_backends() const { return keys(cameras_); }
std::vector<std::string> BackendRegistry::light_backends() const { return keys(lights_); }

Result<Rig> BackendRegistry::make_rig(const nlohmann::json& config) const {
  if (!config.is_object()) return make_error(ErrorCode::kInvalidArgument, "rig config must be a JSON object");
  RigContext ctx{config, {}};
  Rig rig;
  auto stage = build(stages_, "stage", config.value("stage", nlohmann::json::object()), ctx);
  if (!stage) return stage.error();
  rig.stage = std::move(stage.value());
  // The camera and light factories may look at the stage just built (the simulated camera paired with a real stage
  // renders the pose that stage reports): "rig.stage", a non-owning PanTiltStage*, valid as long as the Rig.
  ctx.shared["rig.stage"] = std::shared_ptr<void>(std::shared_ptr<void>(), rig.stage.get());
  auto camera = build(cameras_, "camera", config.value("camera", nlohmann::json::object()), ctx);
  if (!camera) return camera.error();
  rig.camera = std::move(camera.value());
  if (config.contains("light")) {
    auto light = build(lights_, "light", config["light"], ctx);
    if (!light) return light.error();
    rig.light = std::move(light.value());
  }
  return rig;
}

}  // namespace vdrig::rig
