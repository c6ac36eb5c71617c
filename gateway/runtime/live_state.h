// The vehicle at a glance: the latest decoded values the live view, `fleetgw status` and the
// retained MQTT status show (speed, assist, SOC, pack voltage and current, lock states, active
// faults). Fed by every decoded message; never blocks, never allocates on the hot path after
// the first message of each kind.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "motinova/codec.h"
#include "motinova/options.h"

namespace fleetgw::runtime {

struct ActiveFault {
  std::string node;  // "mc", "bms", ...
  int code = -1;
  std::string name;
  std::string severity;
};

struct LockView {
  std::string kind;   // from lock_kinds (U21); empty = not fitted
  std::string state;  // "unknown" until heard
  int state_raw = -1;
};

struct LiveState {
  std::optional<double> speed_kmh;
  std::optional<std::string> assist;
  std::optional<int64_t> assist_raw;
  std::optional<double> range_km;  // MC estimate (mc_status)
  // The limit in force from the MC's settings report (0x5408): its speed-limit field plus the
  // offset when that field is the factory limit (`[command] mc_settings_limit`, a [G] reading).
  std::optional<double> speed_limit_kmh;
  bool settings_limit_is_factory = true;
  std::optional<bool> headlight;
  std::optional<double> soc_pct;
  std::optional<double> pack_voltage_v;
  std::optional<double> pack_current_a;
  std::optional<double> odo_km;
  std::optional<double> motor_temp_c;
  std::optional<bool> charging;
  std::array<LockView, 5> locks;
  std::vector<ActiveFault> faults;  // rebuilt from the latest fault word of each node
  uint64_t messages = 0;

  void update(const motinova::DecodedMessage& message, const motinova::DecodeOptions& options);
  // One compact line: "23.4 km/h | norm | SOC 78% | 47.9 V -3.2 A | seat:locked ... | faults: none"
  std::string line() const;

 private:
  // Active faults per fault-word source node (index = node number).
  std::array<std::vector<ActiveFault>, 16> per_node_;
  void rebuild_faults();
};

}  // namespace fleetgw::runtime
