// vdrigd's session runner: owns the rig and the one capture thread (start, resume, pause/abort, shutdown) and the
// stage commands that share that rig. Every method is called from the daemon's loop thread; the worker reports
// back only through the mutex-guarded state and event queue, and the `wake` callback (the loop's wake-up pipe).
#pragma once

#include <atomic>
#include <deque>
#include <filesystem>
#include <functional>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>

#include "vdrig/capture/daemon.hpp"
#include "vdrig/capture/plan.hpp"
#include "vdrig/capture/process_lock.hpp"

namespace vdrig::capture {

enum class RunState { kIdle, kRunning, kPaused, kCompleted, kFailed, kAborted };
/// "idle", "running", ... as the protocol sends it.
const char* state_name(RunState state);

/// What pause, abort and shutdown ask of a running session (all stop it after the frame in hand).
enum class StopIntent { kNone, kPause, kAbort, kShutdown };

class SessionRunner {
 public:
  /// `config` must outlive the runner; `wake` must be callable from the worker thread.
  SessionRunner(const DaemonConfig& config, std::function<void()> wake);
  ~SessionRunner();  // waits for the worker (it stops on its own only when asked: call shutdown() first)
  SessionRunner(const SessionRunner&) = delete;
  SessionRunner& operator=(const SessionRunner&) = delete;

  bool running();
  /// The session in hand ("" before the first).
  std::string session_name();
  /// The `status` reply: state; the session's name and progress once there is one; the last error if any.
  nlohmann::json status();
  /// State and progress events since the last call, oldest first.
  std::deque<nlohmann::json> take_events();

  /// Builds the configured rig (DaemonConfig::rig_config) and takes its lock, so a daemon with a rig config that does
  /// not build, or a rig another process drives, refuses to start. The error says why.
  Status prepare();

  /// Builds the rig `plan.rig_config` describes (unless it is the one in hand), plans the session on its stage,
  /// creates it in `dir` and starts capturing. Precondition: !running(). Returns the manifest written.
  Result<Manifest> start(const std::string& name, const std::filesystem::path& dir, PlanRequest plan);
  /// Opens the session in `dir` and continues it at its first incomplete view, on the rig its manifest names.
  /// Precondition: !running().
  Status resume(const std::string& name, const std::filesystem::path& dir);

  enum class StopOutcome {
    kStopping,       // a running session stops after the frame in hand
    kAborted,        // a paused or failed session was marked aborted at once
    kNothingToStop,  // no session to stop (`state` says why)
  };
  struct StopReply {
    StopOutcome outcome;
    std::string session;
    RunState state;  // the state when asked
  };
  /// Pause or abort (`what`).
  StopReply stop(StopIntent what);

  /// Whether a `home` or `move` started by start_home/start_move is still under way.
  bool moving();
  /// Starts homing the stage of the rig in hand (else of the configured rig) on a thread of its own, so the daemon
  /// keeps answering; the outcome comes from take_motion_result(). Precondition: !running() && !moving().
  Status start_home();
  /// Starts a move there (kInvalidArgument outside the axis limits, nothing moved), as start_home.
  Status start_move(const PanTilt& target);
  /// The position reached by the finished home/move (or its error), once; nullopt while it runs or when none ran.
  std::optional<Result<PanTilt>> take_motion_result();
  /// `stop`: halts the axes at once (a home/move in progress ends with kCancelled) and pauses a running session
  /// after the frame in hand. What it did, for the reply.
  nlohmann::json stop_motion();

  /// Stops a running session after the frame in hand, waits for the worker and parks the axes at pan = tilt = 0.
  void shutdown();

 private:
  void join_worker();
  /// Builds the rig for `rig_config` (taking its lock: process_lock.hpp) unless the one in hand already is;
  /// `must_match` false takes any rig in hand.
  Status ensure_rig(const nlohmann::json& rig_config, bool must_match);
  void launch(Session session, const std::string& name);
  void finish(const Status& result, const std::string& name);

  const DaemonConfig& config_;
  std::function<void()> wake_;

  // Built on demand; used by the worker while it runs, by home/move otherwise.
  std::optional<rig::Rig> rig_;
  std::optional<ProcessLock> rig_lock_;  // the rig's lock while it is in hand (none for an unlocked rig)
  nlohmann::json rig_config_in_use_;

  std::thread worker_;
  std::atomic<bool> worker_stop_{false};
  std::thread motion_;  // a home/move (start_home/start_move)
  template <typename Motion>
  Status launch_motion(const char* what, Motion motion);
  // Below: shared with the worker, under mutex_.
  std::mutex mutex_;
  StopIntent intent_ = StopIntent::kNone;
  RunState state_ = RunState::kIdle;
  std::string session_name_;
  CaptureProgress progress_;
  nlohmann::json adaptive_;  // adaptive sampling's batches so far (status "adaptive"), null for a fixed scheme
  std::string last_error_, last_error_code_;
  std::deque<nlohmann::json> events_;
  std::string motion_what_;                       // "homing" / "moving" while a home/move runs, else ""
  std::optional<Result<PanTilt>> motion_result_;  // set by the motion thread when it ends
};

}  // namespace vdrig::capture
