#include "session_runner.hpp"

#include "vdrig/capture/adaptive.hpp"

#include "vdrig/core/log.hpp"

namespace vdrig::capture {
namespace fs = std::filesystem;
using nlohmann::json;

const char* state_name(RunState state) {
  switch (state) {
    case RunState::kIdle:
      return "idle";
    case RunState::kRunning:
      return "running";
    case RunState::kPaused:
      return "paused";
    case RunState::kCompleted:
      return "completed";
    case RunState::kFailed:
      return "failed";
    case RunState::kAborted:
      return "aborted";
  }
  return "unknown";
}

SessionRunner::SessionRunner(const DaemonConfig& config, std::function<void()> wake)
    : config_(config), wake_(std::move(wake)) {}

SessionRunner::~SessionRunner() {
  join_worker();
  if (motion_.joinable()) motion_.join();
}

void SessionRunner::join_worker() {
  if (worker_.joinable()) worker_.join();
}

bool SessionRunner::running() {
  std::lock_guard lock(mutex_);
  return state_ == RunState::kRunning;
}

std::string SessionRunner::session_name() {
  std::lock_guard lock(mutex_);
  return session_name_;
}

json SessionRunner::status() {
  std::lock_guard lock(mutex_);
  json j = {{"state", state_name(state_)}};
  if (!session_name_.empty()) {
    j["session"] = session_name_;
    j["views_done"] = progress_.views_done;
    j["views_total"] = progress_.views_total;
    j["view"] = progress_.view;
    j["bracket_index"] = progress_.bracket_index;
    j["exposure_s"] = progress_.exposure_s;
    j["eta_s"] = progress_.eta_s;
    if (!adaptive_.is_null()) j["adaptive"] = adaptive_;
  }
  if (!last_error_.empty()) {
    j["error"] = last_error_;
    j["error_code"] = last_error_code_;
  }
  return j;
}

std::deque<json> SessionRunner::take_events() {
  std::deque<json> pending;
  std::lock_guard lock(mutex_);
  pending.swap(events_);
  return pending;
}

Status SessionRunner::ensure_rig(const json& rig_config, bool must_match) {
  if (rig_ && (!must_match || rig_config == rig_config_in_use_)) return Status::ok();
  rig_.reset();
  rig_lock_.reset();
  auto lock = lock_rig(rig_config);
  if (!lock) return lock.error();
  auto built = config_.make_rig(rig_config);
  if (!built) return built.error();
  rig_lock_ = std::move(lock.value());
  rig_ = std::move(built.value());
  rig_config_in_use_ = rig_config;
  return Status::ok();
}

Status SessionRunner::prepare() { return ensure_rig(config_.rig_config, false); }

Result<Manifest> SessionRunner::start(const std::string& name, const fs::path& dir, PlanRequest plan) {
  join_worker();
  VDRIG_TRY(ensure_rig(plan.rig_config, true));
  plan.stage = rig_->stage->spec();
  // Adaptive sampling needs the planner this daemon was built with (the pipeline's): refused before anything is made.
  if (is_adaptive_scheme(plan.scheme)) VDRIG_TRY(check_adaptive_capture(plan.scheme, dir, plan.rig_config));
  auto manifest = is_adaptive_scheme(plan.scheme) ? plan_adaptive_manifest(plan) : plan_manifest(plan);
  if (!manifest) return manifest.error();
  if (config_.describe_surface) config_.describe_surface(manifest.value());
  auto session = Session::create(dir, manifest.value());
  if (!session) return session.error();
  launch(std::move(session.value()), name);
  return manifest;
}

Status SessionRunner::resume(const std::string& name, const fs::path& dir) {
  join_worker();
  // Locked before its journal is read: a session another process captures is refused with that process's PID.
  auto session = Session::open_for_capture(dir);
  if (!session) return session.error();
  VDRIG_TRY(ensure_rig(session->manifest().rig_config, true));
  launch(std::move(session.value()), name);
  return Status::ok();
}

SessionRunner::StopReply SessionRunner::stop(StopIntent what) {
  std::lock_guard lock(mutex_);
  const StopReply asked{StopOutcome::kNothingToStop, session_name_, state_};
  if (state_ == RunState::kRunning) {
    intent_ = what;
    worker_stop_ = true;
    return {StopOutcome::kStopping, session_name_, asked.state};
  }
  if (what == StopIntent::kAbort && (state_ == RunState::kPaused || state_ == RunState::kFailed)) {
    state_ = RunState::kAborted;
    events_.push_back({{"event", "state"}, {"session", session_name_}, {"state", "aborted"}});
    return {StopOutcome::kAborted, session_name_, asked.state};
  }
  return asked;
}

bool SessionRunner::moving() {
  std::lock_guard lock(mutex_);
  return !motion_what_.empty();
}

template <typename Motion>
Status SessionRunner::launch_motion(const char* what, Motion motion) {
  if (motion_.joinable()) motion_.join();  // the previous one has ended (moving() was false)
  {
    std::lock_guard lock(mutex_);
    motion_what_ = what;
    motion_result_.reset();
  }
  motion_ = std::thread([this, motion] {
    Result<PanTilt> result = make_error(ErrorCode::kInternal, "motion did not run");
    // As the capture worker: no exception may cross the thread boundary.
    try {
      const Status moved = motion(*rig_->stage);
      result = moved ? rig_->stage->position() : Result<PanTilt>(moved.error());
    } catch (const std::exception& e) {
      result = make_error(ErrorCode::kInternal, std::string("stage threw: ") + e.what());
    }
    {
      std::lock_guard lock(mutex_);
      motion_what_.clear();
      motion_result_ = std::move(result);
    }
    wake_();
  });
  return Status::ok();
}

Status SessionRunner::start_home() {
  join_worker();
  VDRIG_TRY(ensure_rig(config_.rig_config, false));
  return launch_motion("homing", [](rig::PanTiltStage& stage) { return stage.home(); });
}

Status SessionRunner::start_move(const PanTilt& target) {
  join_worker();
  VDRIG_TRY(ensure_rig(config_.rig_config, false));
  const rig::StageSpec spec = rig_->stage->spec();
  if (target.pan_rad < spec.pan.min_rad - 1e-12 || target.pan_rad > spec.pan.max_rad + 1e-12 ||
      target.tilt_rad < spec.tilt.min_rad - 1e-12 || target.tilt_rad > spec.tilt.max_rad + 1e-12)
    return make_error(ErrorCode::kInvalidArgument, "target outside the axis limits");
  return launch_motion("moving", [target](rig::PanTiltStage& stage) { return stage.move_to(target); });
}

std::optional<Result<PanTilt>> SessionRunner::take_motion_result() {
  std::optional<Result<PanTilt>> result;
  {
    std::lock_guard lock(mutex_);
    result.swap(motion_result_);
  }
  if (result && motion_.joinable()) motion_.join();  // it has set the result: it is ending
  return result;
}

json SessionRunner::stop_motion() {
  json done = json::object();
  const StopReply paused = stop(StopIntent::kPause);
  if (paused.outcome == StopOutcome::kStopping) done["paused"] = paused.session;
  const std::string what = [&] {
    std::lock_guard lock(mutex_);
    return motion_what_;
  }();
  if (!what.empty()) done["stopped"] = what;
  // The stage's stop() may be called while another thread is in its move_to (devices.hpp): that move then ends.
  if (rig_) {
    const Status halted = rig_->stage->stop();
    if (!halted) {
      done["warning"] = "stopping the axes failed: " + halted.describe();
      log::get("vdrigd")->warn("stop: {}", halted.describe());
    }
  }
  return done;
}

namespace {

/// Adaptive sampling as `status` and the "adaptive_batch" events report it (docs/protocol.md).
json adaptive_status(const AdaptiveProgress& p) {
  json j = {{"batches", p.batches.size()}, {"planned_move_s", p.planned_move_s()}};
  int views = 0;
  for (const auto& b : p.batches) views += static_cast<int>(b.views.size());
  j["views_chosen"] = views;  // by the batches, beyond the base scheme
  if (!p.batches.empty()) j["predicted_error"] = p.batches.back().predicted_error;
  if (p.stopped) j["stopped"] = *p.stopped;
  return j;
}

}  // namespace

void SessionRunner::launch(Session session, const std::string& name) {
  {
    std::lock_guard lock(mutex_);
    state_ = RunState::kRunning;
    session_name_ = name;
    progress_ = {};
    progress_.views_total = static_cast<int>(session.manifest().views.size());
    progress_.views_done = session.completed_view_count();
    adaptive_ = session.manifest().extra.contains("adaptive") ? adaptive_status(adaptive_progress(session)) : json();
    last_error_.clear();
    last_error_code_.clear();
    intent_ = StopIntent::kNone;
    events_.push_back({{"event", "state"}, {"session", name}, {"state", "running"}});
  }
  worker_stop_ = false;
  CaptureOptions options = config_.capture;
  auto bracket = parse_bracket(session.manifest().bracket);
  if (bracket)
    options.bracket = bracket.value();
  else
    options.exposures_s = session.manifest().exposures_s;
  options.stop_requested = &worker_stop_;
  options.on_progress = [this, name](const CaptureProgress& p) {
    {
      std::lock_guard lock(mutex_);
      progress_ = p;
      events_.push_back({{"event", "progress"},
                         {"session", name},
                         {"views_done", p.views_done},
                         {"views_total", p.views_total},
                         {"view", p.view},
                         {"bracket_index", p.bracket_index},
                         {"exposure_s", p.exposure_s},
                         {"view_finished", p.view_finished},
                         {"elapsed_s", p.elapsed_s},
                         {"eta_s", p.eta_s}});
    }
    wake_();
  };
  worker_ = std::thread([this, s = std::move(session), options, name]() mutable {
    Status result = Status::ok();
    // No exception may cross the thread boundary (it would terminate the daemon): a backend that throws (OpenCV, a
    // vendor library) fails the session as kInternal instead, and the daemon keeps serving.
    try {
      if (s.manifest().extra.contains("adaptive")) {
        auto planner = make_view_planner();
        if (!planner) {
          result = planner.error();
        } else {
          AdaptiveOptions adaptive;
          adaptive.capture = options;
          adaptive.on_batch = [this, name](const AdaptiveProgress& p) {
            {
              std::lock_guard lock(mutex_);
              adaptive_ = adaptive_status(p);
              json ev = adaptive_;
              ev["event"] = "adaptive_batch";
              ev["session"] = name;
              events_.push_back(ev);
            }
            wake_();
          };
          result = run_adaptive_session(*rig_, s, *planner.value(), adaptive);
        }
      } else {
        result = run_session(*rig_, s, options, true);
      }
    } catch (const std::exception& e) {
      result = make_error(ErrorCode::kInternal, std::string("capture threw: ") + e.what());
    }
    finish(result, name);
    wake_();
  });
}

void SessionRunner::finish(const Status& result, const std::string& name) {
  std::lock_guard lock(mutex_);
  if (result)
    state_ = RunState::kCompleted;
  else if (result.error().code == ErrorCode::kCancelled)
    state_ = intent_ == StopIntent::kAbort ? RunState::kAborted : RunState::kPaused;
  else
    state_ = RunState::kFailed;
  if (!result) {
    last_error_ = result.error().message;
    last_error_code_ = wire_code(result.error().code);
  }
  json ev = {{"event", "state"}, {"session", name}, {"state", state_name(state_)}};
  if (!result && result.error().code != ErrorCode::kCancelled) {
    ev["error"] = last_error_;
    ev["error_code"] = last_error_code_;
  }
  events_.push_back(ev);
}

void SessionRunner::shutdown() {
  {
    std::lock_guard lock(mutex_);
    if (state_ == RunState::kRunning) {
      intent_ = StopIntent::kShutdown;
      worker_stop_ = true;
    }
  }
  join_worker();  // the worker finishes the frame in hand and parks the axes
  if (motion_.joinable()) {
    if (rig_) (void)rig_->stage->stop();  // a home/move in progress ends now rather than at its timeout
    motion_.join();
  }
  if (rig_) {
    const Status parked = rig_->stage->move_to(PanTilt{0.0, 0.0});
    if (!parked) log::get("vdrigd")->warn("parking failed: {}", parked.describe());
  }
}

}  // namespace vdrig::capture
