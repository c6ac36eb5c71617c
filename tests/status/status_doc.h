// A healthy status document (schema 1) as the runtime's provider produces it; tests break one
// thing at a time.
#pragma once

#include <nlohmann/json.hpp>

namespace fleetgw::status::test {

inline nlohmann::json healthy_status() {
  return nlohmann::json::parse(R"({
    "schema": 1, "version": "0.1.0", "vehicle_id": "bike-0042", "uptime_s": 7300,
    "bus": {"transport": "socketcan", "interface": "can0", "state": "up", "rx_frames": 120345,
            "tx_frames": 812, "tx_failures": 0, "error_frames": 0, "reopens": 0,
            "frame_errors": {"crc": 2, "sequence": 0}, "detail": ""},
    "nodes": [
      {"name": "mc", "online": true, "last_heard_age_s": 0.1, "firmware": "MC_V4.6.2"},
      {"name": "bms", "online": true, "last_heard_age_s": 0.4, "firmware": "BMS_V2.1"},
      {"name": "lock1", "online": true, "last_heard_age_s": 1.2, "firmware": null}
    ],
    "faults": [{"node": "mc", "code": 7, "name": "motor_overtemp_warning", "severity": "warning"}],
    "locks": [{"kind": "seat", "state": "locked"}, {"kind": "frame", "state": "unlocked"}],
    "broker": {"enabled": true, "connected": true, "uri": "ssl://mqtt.example:8883",
               "last_error": ""},
    "outbox": {"depth": 3, "oldest_unsent_age_s": 1.5},
    "disk": {"used_bytes": 52428800, "budget_bytes": 268435456}
  })");
}

}  // namespace fleetgw::status::test
