// The web console's two ways of talking to vdrigd (docs/protocol.md): one connection per request, and one
// subscribed connection whose events are fanned out to every open event stream (EventRelay).
#pragma once

#include <chrono>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "vdrig/core/result.hpp"

namespace vdrig::web {

/// Sends `request` on a connection of its own and returns the daemon's reply line, ok or not (events are skipped).
/// kDisconnected when the daemon cannot be reached or closes first, kTimeout after `timeout_s`.
Result<nlohmann::json> daemon_request(const std::filesystem::path& socket_path, const nlohmann::json& request,
                                      double timeout_s);

/// What one event stream has not sent yet. Bounded: a stream that falls this far behind loses its oldest lines.
class EventQueue {
 public:
  static constexpr std::size_t kMaxQueued = 1000;
  void push(const std::string& line);
  void close();
  /// The next line, or "" after `wait` with nothing queued; false once closed.
  bool pop(std::string& line, std::chrono::milliseconds wait);

 private:
  std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<std::string> lines_;
  bool closed_ = false;
};

/// Holds one `subscribe`d connection to the daemon (reconnecting every second while it is away) and pushes each
/// event line to every subscriber; when the link comes or goes, {"event":"daemon","connected":...} is pushed, and the
/// subscribe reply as {"event":"status", ...status fields}.
class EventRelay {
 public:
  explicit EventRelay(std::filesystem::path socket_path);
  ~EventRelay();
  EventRelay(const EventRelay&) = delete;
  EventRelay& operator=(const EventRelay&) = delete;

  void start();
  /// Ends the thread and closes every subscriber's queue.
  void stop();
  /// A new queue, first holding the last daemon, status, state and progress lines, the last two in the order they
  /// came (so a page starts from the present state).
  std::shared_ptr<EventQueue> subscribe();
  void unsubscribe(const std::shared_ptr<EventQueue>& queue);

 private:
  void loop();
  void publish(const std::string& line);
  void set_connected(bool connected);

  std::filesystem::path socket_path_;
  std::thread thread_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  int connected_ = -1;                                    // -1: not known yet
  std::string last_status_, last_state_, last_progress_;  // replayed to a new subscriber
  bool progress_after_state_ = false;                     // which of the last two came last
  std::vector<std::shared_ptr<EventQueue>> subscribers_;
};

}  // namespace vdrig::web
