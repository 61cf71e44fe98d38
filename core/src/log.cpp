#include "vdrig/core/log.hpp"

#include <spdlog/sinks/base_sink.h>
#include <spdlog/sinks/stdout_color_sinks.h>

#include <cstdio>
#include <mutex>

namespace vdrig::log {
namespace {
std::mutex g_mutex;
spdlog::level::level_enum g_level = spdlog::level::info;

/// stderr, after flushing stdout. Progress goes to stdout, which is block-buffered in a pipe or a file, and log lines
/// to stderr, which is not: without the flush, `vdrig demo 2>&1 | tee log` shows a log line of step 3 before the
/// heading of step 2 still sitting in stdout's buffer. Flushing stdout first writes every line in the order the
/// program produced it, whatever the two streams are connected to.
class StdoutFirstSink final : public spdlog::sinks::sink {
 public:
  void log(const spdlog::details::log_msg& msg) override {
    std::fflush(stdout);
    inner_->log(msg);
  }
  void flush() override { inner_->flush(); }
  void set_pattern(const std::string& pattern) override { inner_->set_pattern(pattern); }
  void set_formatter(std::unique_ptr<spdlog::formatter> formatter) override {
    inner_->set_formatter(std::move(formatter));
  }

 private:
  // The colour sink keeps its own mutex and colours only when stderr is a terminal.
  std::shared_ptr<spdlog::sinks::sink> inner_ = std::make_shared<spdlog::sinks::stderr_color_sink_mt>();
};

/// One sink for every logger: its inner mutex then orders lines of different modules too.
std::shared_ptr<spdlog::sinks::sink> shared_sink() {
  static const auto sink = std::make_shared<StdoutFirstSink>();
  return sink;
}
}  // namespace

std::shared_ptr<spdlog::logger> get(const std::string& module) {
  std::lock_guard lock(g_mutex);
  if (auto existing = spdlog::get(module)) return existing;
  auto logger = std::make_shared<spdlog::logger>(module, shared_sink());
  spdlog::register_logger(logger);
  logger->set_level(g_level);
  logger->set_pattern("[%H:%M:%S.%e] [%n] [%^%l%$] %v");
  return logger;
}

const char* const kLevelNames = "trace, debug, info, warn, error, critical, off";

Status set_level(const std::string& level) {
  const spdlog::level::level_enum parsed = spdlog::level::from_str(level);
  // from_str maps every unknown name to off; only "off" itself means it.
  if (parsed == spdlog::level::off && level != "off")
    return make_error(ErrorCode::kInvalidArgument,
                      "unknown log level \"" + level + "\"; valid levels: " + std::string(kLevelNames));
  std::lock_guard lock(g_mutex);
  g_level = parsed;
  spdlog::apply_all([](const std::shared_ptr<spdlog::logger>& l) { l->set_level(g_level); });
  return Status::ok();
}

}  // namespace vdrig::log
