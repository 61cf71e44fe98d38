#include "daemon_protocol.hpp"

#include <cstdint>
#include <exception>
#include <filesystem>

#include "session_runner.hpp"
#include "vdrig/capture/schemes.hpp"
#include "vdrig/core/geometry.hpp"
#include "vdrig/core/json_text.hpp"
#include "vdrig/core/settings.hpp"
#include "vdrig/rig/lamp.hpp"

namespace vdrig::capture {
namespace fs = std::filesystem;
using nlohmann::json;

const char* wire_code(ErrorCode code) {
  switch (code) {
    case ErrorCode::kIo:
      return "io";
    case ErrorCode::kCorrupt:
      return "corrupt";
    case ErrorCode::kInvalidArgument:
      return "invalid_argument";
    case ErrorCode::kNotFound:
      return "not_found";
    case ErrorCode::kDevice:
      return "device";
    case ErrorCode::kTimeout:
      return "timeout";
    case ErrorCode::kDisconnected:
      return "disconnected";
    case ErrorCode::kNoSpace:
      return "no_space";
    case ErrorCode::kUnsupported:
      return "unsupported";
    case ErrorCode::kCancelled:
      return "cancelled";
    case ErrorCode::kInternal:
      return "internal";
    case ErrorCode::kInUse:
      return "in_use";
  }
  return "unknown";  // not an ErrorCode (a cast integer); -Wswitch keeps the list above complete
}

std::vector<std::string> protocol_error_codes() {
  return {wire::kBadRequest, wire::kUnknownCommand,   wire::kInvalidState, wire::kBusy,
          wire::kTooLong,    wire::kPermissionDenied, wire::kIdleTimeout};
}

json error_reply(const RequestError& error, const json& id) {
  json reply = {{"ok", false}, {"code", error.code}, {"error", error.message}};
  if (!id.is_null()) reply["id"] = id;
  return reply;
}

json Reply::to_json(const json& id) && {
  if (auto* error = std::get_if<RequestError>(&v_)) return error_reply(*error, id);
  json reply = std::move(std::get<json>(v_));
  reply["ok"] = true;
  if (!id.is_null()) reply["id"] = id;
  return reply;
}

bool valid_utf8(std::string_view s) {
  size_t i = 0;
  const size_t n = s.size();
  while (i < n) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c < 0x80) {
      ++i;
      continue;
    }
    size_t len = 0;
    uint32_t cp = 0;
    if (c >= 0xC2 && c <= 0xDF)
      len = 2, cp = c & 0x1F;
    else if (c >= 0xE0 && c <= 0xEF)
      len = 3, cp = c & 0x0F;
    else if (c >= 0xF0 && c <= 0xF4)
      len = 4, cp = c & 0x07;
    else
      return false;
    if (i + len > n) return false;
    for (size_t k = 1; k < len; ++k) {
      const unsigned char cc = static_cast<unsigned char>(s[i + k]);
      if ((cc & 0xC0) != 0x80) return false;
      cp = (cp << 6) | (cc & 0x3F);
    }
    if ((len == 3 && cp < 0x800) || (len == 4 && (cp < 0x10000 || cp > 0x10FFFF)) || (cp >= 0xD800 && cp <= 0xDFFF))
      return false;
    i += len;
  }
  return true;
}

Protocol::Protocol(const DaemonConfig& config, SessionRunner& runner) : config_(config), runner_(runner) {}

const std::map<std::string, Protocol::Command, std::less<>>& Protocol::commands() {
  using T = FieldType;
  static const std::map<std::string, Command, std::less<>> table = {
      {"status", {{}, &Protocol::status}},
      {"subscribe", {{}, &Protocol::subscribe}},
      {"start",
       {{{"session", T::kString, true},
         {"scheme", T::kString, false},
         {"bracket", T::kString, false},
         {"scene", T::kString, false},
         {"rig", T::kObject, false}},
        &Protocol::start}},
      {"pause", {{}, &Protocol::pause}},
      {"abort", {{}, &Protocol::abort}},
      {"resume", {{{"session", T::kString, false}}, &Protocol::resume}},
      {"home", {{}, &Protocol::home}},
      {"move", {{{"pan_deg", T::kNumber, true}, {"tilt_deg", T::kNumber, true}}, &Protocol::move}},
      {"list-sessions", {{}, &Protocol::list_sessions}},
      {"stop", {{}, &Protocol::stop}},
  };
  return table;
}

std::optional<json> Protocol::answer(const std::string& line, bool& subscribed) {
  std::string_view text = line;
  if (!text.empty() && text.back() == '\r') text.remove_suffix(1);
  json id;
  deferred_ = false;
  // Handlers report failures as values. This catch is the backstop for what they call but do not own (the rig
  // factory, describe_surface, allocation): one request must not take the daemon down.
  try {
    json reply = answer_request(text, id, subscribed).to_json(id);
    if (deferred_) {
      deferred_id_ = id;
      return std::nullopt;
    }
    return reply;
  } catch (const std::exception& e) {
    deferred_ = false;
    return error_reply({wire_code(ErrorCode::kInternal), e.what()}, id);
  }
}

Reply Protocol::answer_request(std::string_view line, json& id, bool& subscribed) {
  if (line.empty()) return RequestError{wire::kBadRequest, "empty request"};
  if (!valid_utf8(line)) return RequestError{wire::kBadRequest, "request is not valid UTF-8"};
  auto parsed = parse_json_text(line, "request");
  if (!parsed) return RequestError{wire::kBadRequest, "request is not valid JSON"};
  // A request that says a thing twice (a start's rig config naming its stage twice) has no one meaning.
  if (!parsed->duplicate_keys.empty()) return RequestError{wire::kBadRequest, parsed->duplicate_keys.front()};
  const json& request = parsed->value;
  if (!request.is_object()) return RequestError{wire::kBadRequest, "request must be a JSON object"};
  if (const auto it = request.find("id"); it != request.end()) {
    if (!it->is_string() && !it->is_number_integer())
      return RequestError{wire::kBadRequest, "\"id\" must be a string or an integer"};
    id = *it;
  }
  const auto cmd = request.find("cmd");
  if (cmd == request.end() || !cmd->is_string())
    return RequestError{wire::kBadRequest, "request needs a string \"cmd\""};
  const std::string& name = cmd->get_ref<const std::string&>();
  const auto command = commands().find(name);
  if (command == commands().end()) return RequestError{wire::kUnknownCommand, "unknown command \"" + name + "\""};

  Settings fields(request, "request", {"cmd", "id"});
  std::vector<std::string> known;
  for (const Field& f : command->second.fields) {
    known.emplace_back(f.name);
    if (!fields.has(f.name)) {
      if (f.required) fields.fail(std::string("missing \"") + f.name + "\"");
      continue;
    }
    switch (f.type) {
      case FieldType::kString:
        (void)fields.string(f.name, "");
        break;
      case FieldType::kNumber:
        (void)fields.number(f.name, 0.0);
        break;
      case FieldType::kObject:
        (void)fields.object(f.name, false);
        break;
    }
  }
  fields.reject_unknown(known, "field");
  if (!fields.is_valid(nullptr)) return RequestError{wire::kBadRequest, fields.reasons()};
  return (this->*command->second.handler)(request, subscribed);
}

// --- handlers: the request's fields are present when required and of the declared type ---

namespace {
constexpr const char* kBusyStage = "the stage is homing or moving; wait for it or send stop";
}  // namespace

Reply Protocol::status(const json&, bool&) {
  json status = runner_.status();
  if (runner_.moving()) status["stage"] = "moving";
  return status;
}

Reply Protocol::subscribe(const json&, bool& subscribed) {
  subscribed = true;
  return runner_.status();
}

Reply Protocol::start(const json& request, bool&) {
  if (runner_.running()) return RequestError{wire::kBusy, "a session is running"};
  if (runner_.moving()) return RequestError{wire::kBusy, kBusyStage};
  const std::string name = request.at("session").get<std::string>();
  std::string why;
  if (!valid_session_name(name, &why)) return make_error(ErrorCode::kInvalidArgument, why);
  const fs::path dir = config_.sessions_dir / name;
  std::error_code ec;
  if (fs::exists(dir, ec)) return make_error(ErrorCode::kInvalidArgument, "session " + name + " exists; use resume");
  if (ec) return make_error(ErrorCode::kIo, "cannot look at " + dir.string() + ": " + ec.message());
  json rig_config = request.contains("rig") ? request.at("rig") : config_.rig_config;
  if (request.contains("scene")) {
    if (!rig_config.contains("sim") || !rig_config["sim"].is_object())
      return make_error(ErrorCode::kInvalidArgument, "\"scene\" needs a sim rig");
    rig_config["sim"]["scene"] = request.at("scene");
    // A lamp the config recorded from its own simulated scene (sim::sim_rig_config) is not the new scene's.
    if (auto l = rig_config.find("light");
        l != rig_config.end() && l->is_object() && l->value("position_source", "").rfind("the simulated scene", 0) == 0)
      *l = rig::without_lamp_keys(*l);
  }
  PlanRequest plan;
  plan.rig_config = std::move(rig_config);
  plan.scheme = request.value("scheme", std::string(kDefaultScheme));
  plan.bracket = request.value("bracket", "auto");
  auto manifest = runner_.start(name, dir, std::move(plan));
  if (!manifest) return manifest.error();
  return json{{"session", name},
              {"views_total", manifest->views.size()},
              {"route", manifest->extra.value("route", json::object())}};
}

Reply Protocol::pause(const json&, bool&) {
  const auto stop = runner_.stop(StopIntent::kPause);
  if (stop.outcome != SessionRunner::StopOutcome::kStopping)
    return RequestError{wire::kInvalidState, std::string("no running session (state ") + state_name(stop.state) + ")"};
  return json{{"session", stop.session}, {"note", "stopping after the frame in hand"}};
}

Reply Protocol::abort(const json&, bool&) {
  const auto stop = runner_.stop(StopIntent::kAbort);
  switch (stop.outcome) {
    case SessionRunner::StopOutcome::kStopping:
      return json{{"session", stop.session}, {"note", "stopping after the frame in hand"}};
    case SessionRunner::StopOutcome::kAborted:
      return json{{"session", stop.session}};
    case SessionRunner::StopOutcome::kNothingToStop:
      break;
  }
  return RequestError{wire::kInvalidState, std::string("no running session (state ") + state_name(stop.state) + ")"};
}

Reply Protocol::resume(const json& request, bool&) {
  if (runner_.running()) return RequestError{wire::kBusy, "a session is running"};
  if (runner_.moving()) return RequestError{wire::kBusy, kBusyStage};
  std::string name = runner_.session_name();
  if (request.contains("session")) {
    name = request.at("session").get<std::string>();
    std::string why;
    if (!valid_session_name(name, &why)) return make_error(ErrorCode::kInvalidArgument, why);
  }
  if (name.empty()) return make_error(ErrorCode::kInvalidArgument, "nothing to resume: name a session");
  if (const Status s = runner_.resume(name, config_.sessions_dir / name); !s) return s.error();
  return json{{"session", name}};
}

namespace {

Reply position_reply(const Result<PanTilt>& position) {
  if (!position) return position.error();
  return json{{"pan_deg", rad_to_deg(position->pan_rad)}, {"tilt_deg", rad_to_deg(position->tilt_rad)}};
}

constexpr const char* kBusyMoving = "a session is running; pause or abort it first";

}  // namespace

Reply Protocol::home(const json&, bool&) {
  if (runner_.running()) return RequestError{wire::kBusy, kBusyMoving};
  if (runner_.moving()) return RequestError{wire::kBusy, kBusyStage};
  if (Status started = runner_.start_home(); !started) return started.error();
  deferred_ = true;
  return json::object();
}

Reply Protocol::move(const json& request, bool&) {
  if (runner_.running()) return RequestError{wire::kBusy, kBusyMoving};
  if (runner_.moving()) return RequestError{wire::kBusy, kBusyStage};
  const PanTilt target{deg_to_rad(request.at("pan_deg").get<double>()),
                       deg_to_rad(request.at("tilt_deg").get<double>())};
  if (Status started = runner_.start_move(target); !started) return started.error();
  deferred_ = true;
  return json::object();
}

std::optional<json> Protocol::take_deferred_reply() {
  auto result = runner_.take_motion_result();
  if (!result) return std::nullopt;
  return position_reply(*result).to_json(deferred_id_);
}

Reply Protocol::stop(const json&, bool&) { return runner_.stop_motion(); }

Reply Protocol::list_sessions(const json&, bool&) {
  json list = json::array();
  std::error_code ec;
  for (fs::directory_iterator it(config_.sessions_dir, ec), end; !ec && it != end; it.increment(ec)) {
    const fs::directory_entry& entry = *it;
    const std::string name = entry.path().filename().string();
    std::error_code type_ec;
    if (!entry.is_directory(type_ec) || !valid_session_name(name)) continue;
    // One damaged folder must not hide the others: it is listed with the reason it cannot be opened.
    std::string damage;
    try {
      auto s = Session::open(entry.path());
      if (s) {
        list.push_back({{"session", name},
                        {"views_total", s->manifest().views.size()},
                        {"views_done", s->completed_view_count()},
                        {"scheme", s->manifest().scheme},
                        {"bracket", s->manifest().bracket}});
        continue;
      }
      damage = s.error().message;
    } catch (const std::exception& e) {
      damage = e.what();
    }
    list.push_back({{"session", name}, {"damaged", true}, {"reason", damage}});
  }
  if (ec) return make_error(ErrorCode::kIo, "cannot list " + config_.sessions_dir.string() + ": " + ec.message());
  return json{{"sessions", list}};
}

}  // namespace vdrig::capture
