// Errors in vdrig come in three tiers:
//  1. device and I/O failures are values (Status / Result<T>) the caller must handle;
//  2. bad configuration is rejected once, up front, with the reason: a settings or options struct has
//     `bool is_valid(std::string* why = nullptr) const`, and the function taking it returns kInvalidArgument with
//     that reason (or VDRIG_CHECKs it when its contract makes validity the caller's duty);
//  3. broken invariants are VDRIG_CHECK failures that abort loudly.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <optional>
#include <source_location>
#include <string>
#include <utility>
#include <variant>

namespace vdrig {

enum class ErrorCode {
  kIo,               // file or stream failed (read, write, fsync, rename)
  kCorrupt,          // a file exists but its content is not what its format says
  kInvalidArgument,  // a caller passed something out of contract (sizes, names, values)
  kNotFound,         // a file, device, session or key that should exist does not
  kDevice,           // hardware reported a fault (drive alarm, camera error)
  kTimeout,          // a device did not answer or finish in time
  kDisconnected,     // a device went away (unplugged camera, closed socket)
  kNoSpace,          // disk full (or below the configured reserve)
  kUnsupported,      // a backend or feature not built in / not available here
  kCancelled,        // stopped on request (pause, abort, SIGTERM)
  kInternal,         // a bug surfaced as a value where aborting would lose data
  kInUse,            // a device or rig another process holds (the message names its PID)
};

const char* to_string(ErrorCode code);

/// A failure as a value: a category and a human-readable message naming what failed and why.
struct Error {
  ErrorCode code = ErrorCode::kInternal;
  std::string message;

  std::string describe() const { return std::string(to_string(code)) + ": " + message; }
};

/// Success or an Error. [[nodiscard]] so an unhandled device failure is a compiler warning.
class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(Error error) : error_(std::move(error)) {}  // NOLINT: implicit by design
  static Status ok() { return {}; }

  bool is_ok() const { return !error_.has_value(); }
  explicit operator bool() const { return is_ok(); }
  const Error& error() const { return *error_; }
  std::string describe() const { return is_ok() ? "ok" : error_->describe(); }

 private:
  std::optional<Error> error_;
};

/// A value of type T or an Error.
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : v_(std::move(value)) {}      // NOLINT: implicit by design
  Result(Error error) : v_(std::move(error)) {}  // NOLINT: implicit by design

  bool is_ok() const { return std::holds_alternative<T>(v_); }
  explicit operator bool() const { return is_ok(); }
  T& value() & { return std::get<T>(v_); }
  const T& value() const& { return std::get<T>(v_); }
  T&& value() && { return std::get<T>(std::move(v_)); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  const Error& error() const { return std::get<Error>(v_); }
  Status status() const { return is_ok() ? Status::ok() : Status(error()); }

 private:
  std::variant<T, Error> v_;
};

inline Error make_error(ErrorCode code, std::string message) { return Error{code, std::move(message)}; }

[[noreturn]] void check_failed(const char* expr, const std::string& message, std::source_location where);

}  // namespace vdrig

/// Invariant check: aborts with the expression, a message and the source location. Always on.
#define VDRIG_CHECK(cond, msg)                                                         \
  do {                                                                                 \
    if (!(cond)) ::vdrig::check_failed(#cond, (msg), std::source_location::current()); \
  } while (0)

/// Propagates a failed Status/Result from the enclosing function.
#define VDRIG_TRY(expr)                                       \
  do {                                                        \
    auto&& vdrig_try_status_ = (expr);                        \
    if (!vdrig_try_status_) return vdrig_try_status_.error(); \
  } while (0)
