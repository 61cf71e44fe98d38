#include "vdrig/core/result.hpp"

namespace vdrig {

const char* to_string(ErrorCode code) {
  switch (code) {
    case ErrorCode::kIo:
      return "I/O error";
    case ErrorCode::kCorrupt:
      return "corrupt data";
    case ErrorCode::kInvalidArgument:
      return "invalid argument";
    case ErrorCode::kNotFound:
      return "not found";
    case ErrorCode::kDevice:
      return "device fault";
    case ErrorCode::kTimeout:
      return "timeout";
    case ErrorCode::kDisconnected:
      return "disconnected";
    case ErrorCode::kNoSpace:
      return "no space left";
    case ErrorCode::kUnsupported:
      return "unsupported";
    case ErrorCode::kCancelled:
      return "cancelled";
    case ErrorCode::kInternal:
      return "internal error";
    case ErrorCode::kInUse:
      return "in use";
  }
  return "unknown error";
}

void check_failed(const char* expr, const std::string& message, std::source_location where) {
  std::fprintf(stderr, "vdrig: invariant violated at %s:%u (%s): %s -- %s\n", where.file_name(),
               static_cast<unsigned>(where.line()), where.function_name(), expr, message.c_str());
  std::fflush(stderr);
  std::abort();
}

}  // namespace vdrig
