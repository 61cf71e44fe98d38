#include "vdrig/rig/registry.hpp"

#include <algorithm>
#include <set>

#include "vdrig/core/log.hpp"
#include "vdrig/rig/geometry_config.hpp"
#include "vdrig/rig/lamp.hpp"

namespace vdrig::rig {
namespace {

/// The top-level keys a rig config has whatever its backends: the device sections, the stated geometry
/// (geometry_config.hpp) and the name of the rig's lock (capture/process_lock.hpp).
constexpr const char* kOwnKeys[] = {"stage", "camera", "light", "geometry", "lock"};

template <typename Map>
std::vector<std::string> keys(const Map& m) {
  std::vector<std::string> out;
  for (const auto& [k, v] : m) out.push_back(k);
  return out;
}

std::string join(const std::vector<std::string>& names, const char* separator = ", ") {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : separator) + n;
  return s.empty() ? "(none)" : s;
}

template <typename Entries>
auto build(const Entries& entries, const char* kind, const nlohmann::json& section, RigContext& ctx)
    -> decltype(entries.begin()->second.factory(section, ctx)) {
  if (!section.is_object() || !section.contains("backend") || !section["backend"].is_string())
    return make_error(ErrorCode::kInvalidArgument, std::string("rig config: \"") + kind +
                                                       "\" needs a \"backend\" name; known: " + join(keys(entries)));
  const std::string name = section["backend"].get<std::string>();
  const auto it = entries.find(name);
  if (it == entries.end())
    return make_error(ErrorCode::kInvalidArgument, std::string("rig config: unknown ") + kind + " backend \"" + name +
                                                       "\"; known: " + join(keys(entries)));
  log::get("rig")->debug("creating {} backend {}", kind, name);
  return it->second.factory(section, ctx);
}

/// The backend a device section of `config` names, or "" (no such section, or no backend name: make_rig and
/// check_rig_config report that).
std::string backend_named(const nlohmann::json& config, const char* kind) {
  const auto it = config.find(kind);
  if (it == config.end() || !it->is_object()) return "";
  const auto b = it->find("backend");
  return b != it->end() && b->is_string() ? b->get<std::string>() : "";
}

}  // namespace

void BackendRegistry::add_stage(const std::string& name, Factory<PanTiltStage> f, BackendSpec spec) {
  VDRIG_CHECK(spec.check, "stage backend \"" + name + "\" registered without a settings check (BackendSpec::check)");
  stages_[name] = {std::move(f), std::move(spec)};
}
void BackendRegistry::add_camera(const std::string& name, Factory<Camera> f, BackendSpec spec) {
  VDRIG_CHECK(spec.check, "camera backend \"" + name + "\" registered without a settings check (BackendSpec::check)");
  cameras_[name] = {std::move(f), std::move(spec)};
}
void BackendRegistry::add_light(const std::string& name, Factory<Light> f, BackendSpec spec) {
  VDRIG_CHECK(spec.check, "light backend \"" + name + "\" registered without a settings check (BackendSpec::check)");
  lights_[name] = {std::move(f), std::move(spec)};
}
void BackendRegistry::add_section(const std::string& name, std::function<Status(const nlohmann::json&)> check) {
  sections_[name] = std::move(check);
}
std::vector<std::string> BackendRegistry::stage_backends() const { return keys(stages_); }
std::vector<std::string> BackendRegistry::camera_backends() const { return keys(cameras_); }
std::vector<std::string> BackendRegistry::light_backends() const { return keys(lights_); }

const BackendSpec* BackendRegistry::spec_of(const std::string& kind, const std::string& backend) const {
  const auto find = [&](const auto& entries) -> const BackendSpec* {
    const auto it = entries.find(backend);
    return it == entries.end() ? nullptr : &it->second.spec;
  };
  if (kind == "stage") return find(stages_);
  if (kind == "camera") return find(cameras_);
  if (kind == "light") return find(lights_);
  return nullptr;
}

std::optional<Result<nlohmann::json>> BackendRegistry::check_device_section(const std::string& kind,
                                                                            const std::string& backend,
                                                                            const nlohmann::json& section) const {
  const BackendSpec* spec = spec_of(kind, backend);
  if (!spec) return std::nullopt;
  if (kind != "light") return spec->check(section);
  // The lamp's measured position (lamp.hpp) is the registry's, not the backend's: checked here, stripped for the
  // backend's parser and put back into the effective settings.
  auto lamp = lamp_from_light_section(section);
  auto checked = spec->check(without_lamp_keys(section));
  if (!lamp && !checked)
    return Result<nlohmann::json>(
        make_error(ErrorCode::kInvalidArgument, checked.error().message + "; " + lamp.error().message));
  if (!lamp) return Result<nlohmann::json>(lamp.error());
  if (!checked || !lamp.value() || !checked->is_object()) return checked;
  nlohmann::json effective = checked.value();
  effective.update(lamp_keys(*lamp.value()));
  return Result<nlohmann::json>(std::move(effective));
}

std::vector<std::string> BackendRegistry::top_level_problems(const nlohmann::json& config) const {
  std::vector<std::string> problems;
  if (!config.is_object()) return {"a rig config is a JSON object with \"stage\", \"camera\" and optionally \"light\""};
  // The shared sections this config's devices read, and which backends read each (for the message when unused).
  std::set<std::string> read_here;
  std::map<std::string, std::set<std::string>> readers;
  const auto collect = [&](const char* kind, const auto& entries) {
    const std::string chosen = backend_named(config, kind);
    for (const auto& [name, entry] : entries)
      for (const auto& section : entry.spec.sections) {
        readers[section].insert(name);
        if (name == chosen) read_here.insert(section);
      }
  };
  collect("stage", stages_);
  collect("camera", cameras_);
  collect("light", lights_);
  std::vector<std::string> known(std::begin(kOwnKeys), std::end(kOwnKeys));
  for (const auto& [name, check] : sections_) known.push_back(name);
  std::sort(known.begin(), known.end());
  for (const auto& [key, value] : config.items()) {
    if (std::find(std::begin(kOwnKeys), std::end(kOwnKeys), key) != std::end(kOwnKeys)) continue;
    const auto shared = sections_.find(key);
    if (shared == sections_.end()) {
      problems.push_back("unknown top-level key \"" + key + "\"; known: " + join(known));
      continue;
    }
    if (!read_here.contains(key)) {
      const auto& by = readers[key];
      problems.push_back("\"" + key + "\" is read only by the " + join({by.begin(), by.end()}) +
                         " backend(s), which no device of this config uses");
      continue;
    }
    if (const Status s = shared->second(value); !s) problems.push_back(s.error().message);
  }
  if (const auto lock = config.find("lock"); lock != config.end())
    if (!lock->is_string() || lock->get<std::string>().empty())
      problems.push_back("\"lock\" must be a non-empty string (the name of the rig's lock), got " + lock->dump());
  if (const auto geometry = config.find("geometry"); geometry != config.end())
    if (auto g = geometry_from_section(*geometry); !g) problems.push_back(g.error().message);
  return problems;
}

Result<Rig> BackendRegistry::make_rig(const nlohmann::json& config) const {
  if (!config.is_object()) return make_error(ErrorCode::kInvalidArgument, "rig config must be a JSON object");
  // Every section is validated before any device is opened: a bad light section must not leave a stage homed.
  auto problems = top_level_problems(config);
  for (const char* kind : {"stage", "camera", "light"}) {
    const std::string backend = backend_named(config, kind);
    if (backend.empty()) continue;  // no section, or no name: build() reports it with the known names
    if (auto checked = check_device_section(kind, backend, config[kind]); checked && !*checked)
      problems.push_back(checked->error().message);
  }
  if (!problems.empty()) return make_error(ErrorCode::kInvalidArgument, "rig config: " + join(problems, "; "));
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
    auto light = build(lights_, "light", without_lamp_keys(config["light"]), ctx);
    if (!light) return light.error();
    rig.light = std::move(light.value());
  }
  return rig;
}

}  // namespace vdrig::rig
