#include "daemon_link.hpp"

#include <algorithm>

#include "vdrig/capture/daemon_client.hpp"
#include "vdrig/core/log.hpp"

namespace vdrig::web {
namespace fs = std::filesystem;
using nlohmann::json;

Result<json> daemon_request(const fs::path& socket_path, const json& request, double timeout_s) {
  capture::DaemonClient c;
  VDRIG_TRY(c.connect(socket_path));
  return c.request(request, static_cast<int>(timeout_s * 1000));
}

void EventQueue::push(const std::string& line) {
  {
    std::lock_guard lock(mutex_);
    if (closed_) return;
    if (lines_.size() >= kMaxQueued) lines_.pop_front();
    lines_.push_back(line);
  }
  ready_.notify_one();
}

void EventQueue::close() {
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
  }
  ready_.notify_all();
}

bool EventQueue::pop(std::string& line, std::chrono::milliseconds wait) {
  std::unique_lock lock(mutex_);
  ready_.wait_for(lock, wait, [&] { return closed_ || !lines_.empty(); });
  if (closed_) return false;
  line.clear();
  if (!lines_.empty()) {
    line = std::move(lines_.front());
    lines_.pop_front();
  }
  return true;
}

EventRelay::EventRelay(fs::path socket_path) : socket_path_(std::move(socket_path)) {}

EventRelay::~EventRelay() { stop(); }

void EventRelay::start() {
  thread_ = std::thread([this] { loop(); });
}

void EventRelay::stop() {
  std::vector<std::shared_ptr<EventQueue>> queues;
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
    queues.swap(subscribers_);
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
  for (auto& q : queues) q->close();
}

std::shared_ptr<EventQueue> EventRelay::subscribe() {
  auto queue = std::make_shared<EventQueue>();
  std::lock_guard lock(mutex_);
  if (stopping_) {
    queue->close();
    return queue;
  }
  if (connected_ >= 0) queue->push(json{{"event", "daemon"}, {"connected", connected_ == 1}}.dump());
  // In the order they came: a progress event replayed after a later state event would undo it on the page.
  const std::string* first = progress_after_state_ ? &last_state_ : &last_progress_;
  const std::string* second = progress_after_state_ ? &last_progress_ : &last_state_;
  for (const std::string* line : {static_cast<const std::string*>(&last_status_), first, second})
    if (!line->empty()) queue->push(*line);
  subscribers_.push_back(queue);
  return queue;
}

void EventRelay::unsubscribe(const std::shared_ptr<EventQueue>& queue) {
  std::lock_guard lock(mutex_);
  subscribers_.erase(std::remove(subscribers_.begin(), subscribers_.end(), queue), subscribers_.end());
}

void EventRelay::publish(const std::string& line) {
  std::lock_guard lock(mutex_);
  for (auto& q : subscribers_) q->push(line);
}

void EventRelay::set_connected(bool connected) {
  {
    std::lock_guard lock(mutex_);
    if (connected_ == (connected ? 1 : 0)) return;
    connected_ = connected ? 1 : 0;
    if (!connected) last_status_.clear(), last_state_.clear(), last_progress_.clear();
  }
  publish(json{{"event", "daemon"}, {"connected", connected}}.dump());
}

void EventRelay::loop() {
  auto logger = log::get("web");
  auto stopping = [this] {
    std::lock_guard lock(mutex_);
    return stopping_;
  };
  while (!stopping()) {
    capture::DaemonClient c;
    Status linked = c.connect(socket_path_);
    if (linked) linked = c.send({{"cmd", "subscribe"}});
    while (linked && !stopping()) {
      auto line = c.read_line(200);  // short, so that stop() is seen soon
      if (!line) {
        if (line.error().code == ErrorCode::kTimeout) continue;
        linked = line.status();
        break;
      }
      json j = json::parse(line.value(), nullptr, false);
      if (j.is_discarded() || !j.is_object()) continue;
      if (!j.contains("event")) {  // the subscribe reply: the status at this moment
        if (!j.value("ok", false)) {
          linked = make_error(ErrorCode::kDisconnected, "vdrigd refused the subscription: " + j.value("error", ""));
          break;
        }
        j.erase("ok");
        j["event"] = "status";
        set_connected(true);
        std::lock_guard lock(mutex_);
        last_status_ = j.dump();
        last_state_.clear();
        last_progress_.clear();
        for (auto& q : subscribers_) q->push(last_status_);
        continue;
      }
      const std::string kind = j.value("event", "");
      const std::string text = j.dump();  // re-serialised: one line, whatever spacing the daemon used
      std::lock_guard lock(mutex_);
      if (kind == "state") last_state_ = text, progress_after_state_ = false;
      if (kind == "progress") last_progress_ = text, progress_after_state_ = true;
      for (auto& q : subscribers_) q->push(text);
    }
    if (!linked) logger->debug("event relay: {}", linked.describe());
    set_connected(false);
    std::unique_lock lock(mutex_);
    wake_.wait_for(lock, std::chrono::seconds(1), [this] { return stopping_; });
  }
}

}  // namespace vdrig::web
