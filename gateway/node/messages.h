// The slice of the MOTINOVA catalogue the IoT node acts on (spec §3.2-§3.6, §3.8): the IDs and
// function codes it sends and waits for, and builders for the frames it transmits.
//
// Contract:
//  * Pure values and pure functions; nothing here reads a clock or touches the bus.
//  * Messages are identified by (CAN ID, function code), as the spec does (§2.1). The node's
//    behaviour keys on these numbers, not on catalogue names, so that renaming a catalogue entry
//    cannot silently change what the node answers.
//  * Builders produce frames that are byte-identical to the catalogue's (keywords in ASCII,
//    space-padded model-info blocks, fault words laid out per DecodeOptions, U2/U3).
#pragma once

#include <compare>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "motinova/can.h"
#include "motinova/frame.h"
#include "motinova/options.h"

namespace fleetgw::node {

// (CAN ID, function code): how the node recognises a message.
struct MessageKey {
  uint16_t can_id = 0;
  uint8_t function = 0;
  friend auto operator<=>(const MessageKey&, const MessageKey&) = default;
  bool matches(const motinova::AppFrame& f) const {
    return f.can_id == can_id && f.function == function;
  }
};

namespace ids {
inline constexpr uint16_t kMcBroadcast = 0x710;
inline constexpr uint16_t kMcToObc = 0x713;  // where the MC answers OBC/IOT reads (U14)
inline constexpr uint16_t kMcToIot = 0x716;  // undefined in V4.6.2; listened to just in case (U14)
inline constexpr uint16_t kBmsBroadcast = 0x720;
inline constexpr uint16_t kBmsToCdl = 0x725;
inline constexpr uint16_t kObcBroadcast = 0x730;
inline constexpr uint16_t kIotBroadcast = 0x760;
inline constexpr uint16_t kIotToMc = 0x761;
inline constexpr uint16_t kIotToBms = 0x762;
inline constexpr uint16_t kIotToObc = 0x763;

// Lock k (0-based): command ID 0x767 + k, broadcast ID 0x770 + 0x10 * k (§3.5.4, §3.6).
inline constexpr uint16_t lock_command_id(int k) {
  return static_cast<uint16_t>(0x767 + k);
}
inline constexpr uint16_t lock_broadcast_id(int k) {
  return static_cast<uint16_t>(0x770 + 0x10 * k);
}
// F = 0x80 + 0x10 * k; F: read info, F+1: read status, F+2: LOCK, F+3: UNLOCK.
inline constexpr uint8_t lock_function_base(int k) {
  return static_cast<uint8_t>(0x80 + 0x10 * k);
}
}  // namespace ids

namespace fn {
// IOT broadcasts on 0x760 (§3.5.1).
inline constexpr uint8_t kIotShutdown = 0x10;
inline constexpr uint8_t kIotLock = 0x11;
inline constexpr uint8_t kIotUnlock = 0x12;
inline constexpr uint8_t kIotModelInfo = 0x13;
inline constexpr uint8_t kIotReady = 0x14;
inline constexpr uint8_t kIotFaults = 0x15;
// Peers.
inline constexpr uint8_t kMcReady = 0x13;     // 0x710/0x1305
inline constexpr uint8_t kMcOdometer = 0x15;  // 0x710/0x1510
inline constexpr uint8_t kMcSettings = 0x54;  // 0x713/0x5408
inline constexpr uint8_t kMcReadSettings = 0x33;
inline constexpr uint8_t kMcReadOdometer = 0x35;
inline constexpr uint8_t kBmsShutdown = 0x13;  // 0x720/0x1308
inline constexpr uint8_t kBmsStatus = 0x10;
inline constexpr uint8_t kBmsCells = 0x11;
inline constexpr uint8_t kBmsFaults = 0x12;
inline constexpr uint8_t kBmsNameplate = 0x14;
inline constexpr uint8_t kBmsModelInfo = 0x15;
inline constexpr uint8_t kBmsExtra = 0x18;
inline constexpr uint8_t kBmsPackStats = 0x50;  // 0x725/0x5028
inline constexpr uint8_t kObcShutdown = 0x10;   // 0x730/0x1008
inline constexpr uint8_t kObcModelInfo = 0x11;
inline constexpr uint8_t kObcReady = 0x14;          // 0x730/0x1405
inline constexpr uint8_t kObcReadModel = 0x70;      // 0x763/0x7000
inline constexpr uint8_t kObcOrderShutdown = 0x70;  // 0x763/0x7008 (same function, mode write)
inline constexpr uint8_t kLockStatus = 0x10;
inline constexpr uint8_t kLockModelInfo = 0x12;
}  // namespace fn

namespace keyword {
inline constexpr std::string_view kReady = "READY";
inline constexpr std::string_view kShutdown = "SHUTDOWN";
inline constexpr std::string_view kLock = "LOCK";
inline constexpr std::string_view kUnlock = "UNLOCK";
}  // namespace keyword

// Lock-state values of 0x7n0/0x1010 byte 5 (U19 best guess; the names are configurable in the
// decoder, the numbers the node acts on are not).
namespace lock_state {
inline constexpr uint8_t kUnknown = 0;
inline constexpr uint8_t kUnlocked = 1;
inline constexpr uint8_t kLocked = 2;
inline constexpr uint8_t kUnlocking = 3;
inline constexpr uint8_t kLocking = 4;
inline constexpr uint8_t kUnlockFailed = 5;
inline constexpr uint8_t kLockFailed = 6;
}  // namespace lock_state
inline constexpr std::size_t kLockStateOffset = 5;
inline constexpr std::size_t kLockStatusLength = 16;

// IOT fault bits (U18: we define them for our own gateway, GPS fixed at 0x0004 by the spec).
namespace iot_fault {
inline constexpr uint32_t kUplinkModule = 0x0001;  // LTE / cellular uplink
inline constexpr uint32_t kBle = 0x0002;
inline constexpr uint32_t kGps = 0x0004;
}  // namespace iot_fault

// True when `frame` carries exactly the ASCII keyword (READY, SHUTDOWN...).
bool is_keyword(const motinova::AppFrame& frame, std::string_view keyword);

// The lock state byte of a lock status frame from lock `k`, or nullopt for any other frame.
std::optional<uint8_t> lock_state_of(const motinova::AppFrame& frame, int k);

// A read request (mode 0x11, no data): COMMAND = function << 8.
motinova::AppFrame read_request(uint16_t can_id, uint8_t function);
// A keyword message (READY, SHUTDOWN, LOCK, UNLOCK) with the given mode.
motinova::AppFrame keyword_frame(uint16_t can_id, motinova::Mode mode, uint8_t function,
                                 std::string_view keyword);
// The 64-byte MODEL/SN/HW/FW block on 0x760/0x1340, each field space-padded to 16 bytes.
// Throws std::invalid_argument if a field is longer than 16 bytes or not printable ASCII.
motinova::AppFrame model_info_frame(std::string_view model, std::string_view serial,
                                    std::string_view hw, std::string_view fw);
// The IOT fault word 0x760/0x1504 in the wire layout the decode options describe (U2, U3).
motinova::AppFrame fault_word_frame(uint32_t normalised, const motinova::DecodeOptions& options);

// "V" + version + "_" + date, e.g. format_firmware("0.1.0", "20250101") = "V0.1.0_20250101".
// Throws std::invalid_argument when the date is not 8 digits or the result exceeds 16 bytes.
std::string format_firmware(std::string_view version, std::string_view yyyymmdd);

}  // namespace fleetgw::node
