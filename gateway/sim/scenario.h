// Simulator scenarios: what bike is simulated (seed, device strings, fitted locks, initial pack
// and odometer), the ride it does (a speed profile) and what happens to it on the way (faults,
// jammed or silent locks, bus trouble, power events). Scenarios are TOML files in
// config/scenarios/; docs/simulator.md documents the schema.
//
// Contract:
//  * A Scenario is a plain value type; it holds no I/O handle and no clock. Times in it are
//    offsets from the scenario start, except `start`, the virtual epoch of the timeline.
//  * parse_scenario()/load_scenario() accept only the documented schema. An unknown key, a value
//    of the wrong type or a value out of range throws ScenarioError whose what() names the file,
//    the line and the full key ("ride.toml:12: ride[2].speed_kmh: expected a number in 0..60,
//    got 75"); file(), line() and key() return the parts separately.
//  * Events come out sorted by time (stable: same time keeps file order).
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "motinova/bytes.h"
#include "motinova/can.h"
#include "motinova/frame.h"

namespace fleetgw::sim {

using motinova::Micros;

class ScenarioError : public std::runtime_error {
 public:
  ScenarioError(std::string file, std::size_t line, std::string key, const std::string& what);
  const std::string& file() const { return file_; }
  std::size_t line() const { return line_; }  // 0 when the error is not tied to a line
  const std::string& key() const { return key_; }

 private:
  std::string file_;
  std::size_t line_;
  std::string key_;
};

// MODEL / SN / HW / FW strings of a node's 64-byte model-info block (16 ASCII characters each).
struct DeviceStrings {
  std::string model;
  std::string serial;
  std::string hw;
  std::string fw;
};

// One leg of the speed profile. The simulated rider accelerates/brakes towards `speed_kmh`
// (never above the MC's effective speed limit) and holds it, with a little seeded wobble.
struct RideSegment {
  double duration_s = 0;
  double speed_kmh = 0;
  std::optional<uint8_t> assist;  // rider changes the assist level on the OBC at segment start
  double grade_pct = 0;           // road gradient, + uphill
  std::size_t line = 0;           // source line, for diagnostics
};

enum class Action : uint8_t {
  kFault,          // set bits of a node's fault word (node, bits)
  kClear,          // clear bits of a node's fault word (node, bits; 0 = all)
  kJamLock,        // the lock's next actuations fail (state 5 / 6, stall fault bit)
  kUnjamLock,      // the lock works again
  kSilenceNode,    // node stops transmitting and answering (optionally for duration)
  kRestoreNode,    // node back on the bus
  kCorrupt,        // the next `count` messages of `node` (any node if absent) are damaged
  kGarbage,        // `count` CAN frames of random bytes on random MOTINOVA IDs
  kPowerOff,       // user presses the OBC power key: OBC SHUTDOWN, system off after ~1 s
  kPowerOn,        // system powered again: boot, MC handshakes
  kBmsAutoOff,     // BMS SHUTDOWN (auto-off), output off after ~1 s
  kLock,           // lock actuated locally (key / button on the lock), same path as a write
  kUnlock,         // idem
  kPlugCharger,    // charger connected with current_a
  kUnplugCharger,  // charger removed
  kSwapBattery,    // another pack in the frame: BMS serial (+ SOH, cycles, SOC) change at once
};
std::string_view action_name(Action a);

enum class Corruption : uint8_t {
  kBitFlip,   // one bit flipped in one segment: CRC (or header) error at the receiver
  kTruncate,  // only the first half of the segments sent: restart/gap/truncation at the receiver
};

struct ScenarioEvent {
  Micros at{0};  // offset from scenario start
  Action action = Action::kFault;
  motinova::Node node = motinova::Node::kBroadcast;  // kBroadcast = "any" for kCorrupt
  uint32_t bits = 0;   // kFault/kClear: bits of the normalised fault word
  Micros duration{0};  // kSilenceNode: auto-restore after this (0 = until restore)
  Corruption corruption = Corruption::kBitFlip;
  uint32_t count = 1;    // kCorrupt: messages, kGarbage: CAN frames
  double current_a = 0;  // kPlugCharger
  // kSwapBattery: the new pack's serial, and what it reports (absent: unchanged).
  std::string serial{};
  std::optional<uint8_t> soh_pct{};
  std::optional<uint16_t> cycles{};
  std::optional<double> soc_pct{};
  std::size_t line = 0;
};

inline constexpr std::size_t kSimLocks = 5;

// One waypoint of the scenario's route (WGS-84 degrees); gateway/sim/route.h walks it.
struct GeoPoint {
  double lat_deg = 0;
  double lon_deg = 0;
};

struct Scenario {
  std::string name = "unnamed";
  std::string description;
  std::string source = "<built-in>";  // file the scenario came from
  uint64_t seed = 1;
  Micros start{1'717'228'800'000'000};  // 2024-06-01T08:00:00Z: the virtual epoch
  Micros duration{0};                   // 0 = ride length + 60 s (see effective_duration())

  // [bike]
  double soc_pct = 80;
  double odo_km = 1234.5;
  uint16_t capacity_mah = 14'000;
  uint16_t cycles = 42;
  uint8_t soh_pct = 97;
  double speed_limit_kmh = 25;
  uint8_t wheel_circumference_cm = 220;
  double ambient_c = 20;
  uint8_t initial_assist = 2;  // NORM
  bool headlight = false;
  bool vehicle_locked = false;   // initial one-touch vehicle lock state (0x760 LOCK/UNLOCK)
  bool locks_locked = true;      // initial state of every fitted physical lock
  bool iot_controls_acc = true;  // after an IOT SHUTDOWN the IOT cuts ACC ~1 s later
  // The MC ignores every write (assist/light, settings, CLEAR...; reads are still answered):
  // a firmware that does not take remote commands, so a test can show `failed`.
  bool mc_ignores_writes = false;
  // Kind of lock fitted at LOCK 1..5 (node 7..B); empty = not fitted.
  std::array<std::string, kSimLocks> lock_kinds{"seat", "frame", "steering", "battery", "other"};
  DeviceStrings mc{"MNV-M510", "MC24060100123", "HW1.2", "V4.6.2_20240115"};
  DeviceStrings bms{"MNV-BP48-14A", "BP24050300456", "HW2.0", "V2.3.1_20231120"};
  DeviceStrings obc{"MNV-D20", "OB24052200789", "HW1.0", "V1.8.0_20240301"};
  DeviceStrings lock{"MNV-LK2", "LK2405", "HW1.1", "V1.2.0_20231005"};  // serial gets "-n"

  // [bus]: how the simulated nodes encode (uncertain readings U1/U2).
  motinova::CrcOrder crc_order = motinova::CrcOrder::kBig;
  motinova::ByteOrder data_order = motinova::ByteOrder::kBig;

  std::vector<RideSegment> ride;
  std::vector<ScenarioEvent> events;
  // [[route]]: the path the bike follows, by the odometer's distance (empty: no position).
  std::vector<GeoPoint> route;

  Micros ride_duration() const;
  Micros effective_duration() const;
  bool lock_fitted(std::size_t index) const { return !lock_kinds.at(index).empty(); }
};

// Parses TOML text; `source_name` is used in error messages and stored in Scenario::source.
Scenario parse_scenario(std::string_view toml_text, std::string_view source_name);
// Reads and parses a file; a missing/unreadable file is a ScenarioError with line 0.
Scenario load_scenario(const std::filesystem::path& path);

// Directory of the bundled scenarios (config/scenarios in the source tree).
std::filesystem::path bundled_scenario_dir();

}  // namespace fleetgw::sim
