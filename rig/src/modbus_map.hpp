// Holding-register map of one pan or tilt drive as the modbus-tcp / modbus-rtu stage expects it (docs/rig-modbus.md
// is the reference for drive integrators; keep the two in step). Plain constants, no libmodbus, so the test's
// simulated drives share them.
#pragma once

#include <cstdint>

namespace vdrig::rig::modbus_map {

// Offsets from the drive's register base ("register_base" setting, default 0). The writable block 0..6 is laid out
// so a move is ONE "write multiple registers" (FC16) request: the drive never sees a move command with a stale
// target or speed.
inline constexpr int kProfileVelocity = 0;  // 2 registers, uint32 counts/s
inline constexpr int kProfileAccel = 2;     // 2 registers, uint32 counts/s^2
inline constexpr int kTargetPosition = 4;   // 2 registers, int32 encoder counts
inline constexpr int kCommand = 6;          // 1 register, see Command; the drive resets it to 0 on acceptance
inline constexpr int kStatus = 7;           // 1 register, see status bits
inline constexpr int kActualPosition = 8;   // 2 registers, int32 encoder counts
inline constexpr int kFaultCode = 10;       // 1 register, drive-specific code, 0 = none
inline constexpr int kRegisterCount = 11;
inline constexpr int kWritableCount = 7;  // registers 0..6
inline constexpr int kReadbackCount = 4;  // registers 7..10 (status, actual position, fault code)
// What the stage polls while a drive works: the command register too, so a command the drive refused (left in the
// register instead of reset to 0) is seen as such rather than ending as a timeout.
inline constexpr int kPollFirst = kCommand;  // registers 6..10
inline constexpr int kPollCount = kRegisterCount - kCommand;

enum Command : uint16_t {
  kCmdNone = 0,
  kCmdMove = 1,        // absolute move to kTargetPosition with the profile velocity/acceleration
  kCmdHome = 2,        // reference run; the drive sets its actual position to 0 at the reference
  kCmdStop = 3,        // decelerate to standstill
  kCmdClearFault = 4,  // reset a latched fault
};

inline constexpr uint16_t kStatusInPosition = 1u << 0;
inline constexpr uint16_t kStatusHomed = 1u << 1;
inline constexpr uint16_t kStatusFault = 1u << 2;
inline constexpr uint16_t kStatusMoving = 1u << 3;

/// Order of the two 16-bit registers of a 32-bit value. Modbus fixes only the byte order inside a register (big
/// endian); vendors disagree on the word order, so it is a setting ("word_order": "high-first" | "low-first").
enum class WordOrder { kHighFirst, kLowFirst };

inline void put_u32(uint16_t* regs, uint32_t v, WordOrder order) {
  const uint16_t hi = static_cast<uint16_t>(v >> 16), lo = static_cast<uint16_t>(v & 0xffffu);
  regs[0] = order == WordOrder::kHighFirst ? hi : lo;
  regs[1] = order == WordOrder::kHighFirst ? lo : hi;
}
inline uint32_t get_u32(const uint16_t* regs, WordOrder order) {
  const uint32_t hi = order == WordOrder::kHighFirst ? regs[0] : regs[1];
  const uint32_t lo = order == WordOrder::kHighFirst ? regs[1] : regs[0];
  return (hi << 16) | lo;
}
inline void put_i32(uint16_t* regs, int32_t v, WordOrder order) { put_u32(regs, static_cast<uint32_t>(v), order); }
inline int32_t get_i32(const uint16_t* regs, WordOrder order) { return static_cast<int32_t>(get_u32(regs, order)); }

}  // namespace vdrig::rig::modbus_map
