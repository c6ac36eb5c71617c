// fleetgw's configuration: the schema of config/fleetgw.toml as plain value types, and its
// loader.
//
// Contract: load_config() either returns a fully validated Config or throws ConfigError listing
// EVERY problem found, each naming file, line and key ("fleetgw.toml:12: can.transport: expected
// one of socketcan, replay, udp, sim, got \"cam\""). Unknown keys, wrong types and out-of-range
// values are all errors: a typo must never silently fall back to a default. Every option has a
// default, so an empty file is a valid configuration. Numbers must be finite (nan/inf are
// refused), and the path must name a regular file (a directory is refused, never read as empty).
//
// These are the checks of the file on its own. The checks that need the machine (files named
// by the config exist, trusted keys decode, broker credentials policy...) live in
// gateway/cli/check_config.h, shared by `fleetgw check-config` and `fleetgw run`.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "motinova/options.h"

namespace fleetgw::config {

struct ConfigError : std::runtime_error {
  explicit ConfigError(std::vector<std::string> problems);
  std::vector<std::string> problems;
};

struct VehicleConfig {
  std::string id = "bike-0001";
  // Issue 28: the groups the vehicle belongs to (e.g. "berlin-north"); a delegation may be
  // scoped to a group instead of vehicle ids. Each 1..64 of [A-Za-z0-9._-], at most 32.
  std::vector<std::string> groups;
  // Issue 27: the GBFS vehicle type (vehicle_type_id) of this bike: a GBFS zone rule naming
  // vehicle types applies only when it names this one. Empty: only rules for every type.
  std::string type_id;
};

struct LogConfig {
  std::string level = "info";  // trace, debug, info, warn, error, critical, off
};

struct CanConfig {
  std::string transport = "socketcan";  // socketcan | replay | udp | sim
  std::string interface = "can0";
  std::string replay_file;
  double replay_speed = 0.0;  // 0 = as fast as possible, 1 = recorded speed
  std::string udp_local = "127.0.0.1:20000";
  std::string udp_remote = "127.0.0.1:20001";
  int reassembly_gap_ms = 100;
};

struct NodeIdentity {
  std::string model = "FLEETGW-IOT";
  std::string serial = "SN0000000001";
  std::string hw = "V1.0.0_20261101";
};

struct NodeSection {
  NodeIdentity identity;
  int offline_timeout_ms = 3000;
  int fault_stale_ms = 2000;
  int request_retry_ms = 200;
  int request_timeout_ms = 1000;
  int model_info_period_ms = 10000;
  int lock_status_poll_ms = 2000;
  int bms_poll_ms = 1000;
  int pack_stats_poll_ms = 60000;
  bool answer_mc_handshake = false;  // U13
};

struct SimConfig {
  std::string scenario = "config/scenarios/demo.toml";
  double speed = 1.0;  // time acceleration
  int64_t seed = 0;    // 0 = use the scenario's seed
  // Start the simulated timeline at the current wall-clock time instead of the scenario's
  // start_utc, so records and commands carry present-day times (the live demo).
  bool start_now = true;
  // Symlink to a pty on which the simulated bike's GNSS receiver writes NMEA for the
  // scenario's [[route]] (a gpsd reads it); empty = no simulated receiver.
  std::string nmea_pty;
  // Lock-step: the bus's time advances with what the gateway has processed, never past it
  // (a loaded machine slows the ride instead of making the bus "fall behind"); the speed is a
  // ceiling. For tests and measurements of bus-time behaviour (docs/simulator.md).
  bool lockstep = false;
};

struct StorageConfig {
  std::string path = "/var/lib/fleetgw/fleetgw.db";
  int max_mb = 256;
  std::string synchronous = "normal";  // normal | full
  int flush_ms = 200;
};

struct MqttConfig {
  bool enabled = false;
  std::string uri = "ssl://localhost:8883";
  std::string topic_prefix = "fleet/v1";
  std::string ca_file;
  std::string cert_file;
  std::string key_file;
  std::string username;
  std::string password;
  bool verify_server = true;
  int keepalive_s = 30;
  bool tcp_nodelay = true;
  int max_inflight = 64;
  int qos = 1;            // every record but live telemetry, and the status
  int telemetry_qos = 0;  // live telemetry (newest sample younger than live_telemetry_max_age_ms)
  int live_telemetry_max_age_ms = 10'000;
  int status_interval_ms = 60'000;  // retained online status refresh; 0 = only on connect
  int state_interval_ms = 5000;  // retained vehicle state: on a change, at most this often; 0 = off
  double state_min_move_m = 20;  // ...and a new position only once this far from the last one
  int batch_max_samples = 200;
  int batch_max_ms = 5000;
  int reconnect_min_ms = 1000;
  int reconnect_max_ms = 60000;
  // MQTT 5 (docs/uplink.md, "MQTT 5"): "5" (refused publishes are seen) or "3.1.1" (fallback).
  std::string protocol = "5";
  std::int64_t session_expiry_s = 86'400;  // MQTT 5: the broker keeps the session this long
  std::int64_t will_delay_s = 15;          // MQTT 5: last will only after this long offline
};

struct TelemetryConfig {
  int riding_interval_ms = 1000;
  int parked_interval_ms = 60000;
};

struct RideConfig {
  double moving_speed_kmh = 3.0;
  int stationary_end_s = 600;
};

struct FaultConfig {
  int debounce_ms = 3000;
};

// [alarms] (docs/data-model.md, "Operator alarms").
struct AlarmsConfig {
  bool enabled = true;
  double movement_speed_kmh = 1.0;
  double movement_rpm = 20.0;
  int movement_debounce_ms = 2000;
  int movement_clear_s = 30;
  std::vector<int> low_battery_pct{20, 10, 5};  // strictly descending, 1..99
  double low_battery_hysteresis_pct = 3.0;
  int battery_silent_ms = 10000;
};

// [parked] (docs/data-model.md "Parked mode"): the gateway's rates while the vehicle is locked
// and still; the first movement, unlock or alarm restores the normal rates at once.
struct ParkedSection {
  bool enabled = true;
  int settle_s = 30;                 // locked and still this long before parked
  int poll_interval_ms = 300'000;    // slow poll blocks (own period >= 5 s) at most this often
  int telemetry_batch_ms = 300'000;  // an uplink telemetry batch waits up to this long
  int stale_poll_ms = 1900;  // stale-rule reads (< 5 s) at most this often; < fault_stale_ms
};

// [gnss]: the position from a GNSS receiver through gpsd (docs/location.md).
struct GnssConfig {
  bool enabled = false;
  std::string gpsd = "localhost:2947";  // host:port of gpsd
  int max_age_ms = 3000;                // a fix older than this is not current
  int reconnect_max_ms = 30000;         // backoff cap while gpsd is unreachable
};

// [geofence]: zones enforced on the bike (issue 14, docs/location.md "Geofences"); needs [gnss].
// Bundles are verified with [command.trusted_keys].
struct GeofenceConfig {
  bool enabled = false;
  // The bundle in force, kept as received (signature included).
  std::string bundle_file = "/var/lib/fleetgw/zones.pb";
  double margin_m = 10.0;                 // hysteresis: this far past a boundary...
  int min_dwell_ms = 3000;                // ...for this long without interruption
  int speed_ramp_ms = 10'000;             // slow zone: down from the limit in force
  int assist_fade_ms = 8000;              // no-ride zone: assistance down to off
  int restore_ramp_ms = 5000;             // after a zone: back up
  int own_limit_kmh = 25;                 // the bike's own limit (MC's unknown)
  bool refuse_ride_ending_locks = false;  // no-parking zones: refuse, not only report
  // Bundles over MQTT ([mqtt] enabled): the retained fleet-wide topic ("" = "<topic_prefix>/
  // zones"), optionally the vehicle's own "<topic_prefix>/<vehicle>/zones" too, and the largest
  // payload read (larger ones are refused unread).
  std::string bundle_topic;
  bool vehicle_bundles = false;
  int max_bundle_bytes = 1 << 20;
};

struct CommandConfig {
  std::map<std::string, std::string> trusted_keys;  // key id -> base64 Ed25519 public key
  // Issue 28: the fleet's root keys (key id -> base64 Ed25519 public key): they sign
  // delegations (scoped, expiring keys) and revocation lists, never commands.
  std::map<std::string, std::string> root_keys;
  int clock_skew_s = 30;
  double interlock_speed_kmh = 1.0;
  int interlock_motor_s = 5;
  int confirm_timeout_ms = 3000;
  int retries = 1;
  // [G] MC settings report 0x5408 byte 2: "factory" (the factory speed limit, best guess) or
  // "effective" (the limit in force); remote speed-limit commands compute the 0x3408 offset
  // from the factory limit.
  std::string mc_settings_limit = "factory";
};

struct StatusConfig {
  std::string socket = "/run/fleetgw/status.sock";  // `fleetgw status` asks here; "" = off
};

struct Config {
  std::filesystem::path source;  // file it was loaded from (empty for defaults)
  // Line of every key present in the file ("mqtt.uri" -> 12), for messages about values that
  // are checked after loading.
  std::map<std::string, int, std::less<>> key_lines;
  std::string display_name;  // the file name messages use (the `name` given to parse_config)
  VehicleConfig vehicle;
  LogConfig log;
  CanConfig can;
  motinova::DecodeOptions protocol;
  NodeSection node;
  SimConfig sim;
  StorageConfig storage;
  MqttConfig mqtt;
  TelemetryConfig telemetry;
  RideConfig ride;
  FaultConfig faults;
  AlarmsConfig alarms;
  ParkedSection parked;
  GnssConfig gnss;
  GeofenceConfig geofence;
  CommandConfig command;
  StatusConfig status;

  // "fleetgw.toml:12: mqtt.uri" (or "fleetgw.toml: mqtt.uri" for a key the file does not set):
  // the prefix of a message about `key`, in the loader's format.
  std::string where(std::string_view key) const;
};

// Loads and validates a TOML file.
Config load_config(const std::filesystem::path& file);
// Parses TOML text; `name` is used in messages.
Config parse_config(std::string_view toml_text, const std::string& name);

// Protocol option spellings shared with the decode tool's command-line flags.
motinova::CrcOrder parse_crc_order(std::string_view s);    // be | le | auto
motinova::ByteOrder parse_byte_order(std::string_view s);  // be | le
motinova::FaultWordLayout parse_fault_layout(
    std::string_view s);  // documented | swapped | two_words_low_first
motinova::McVoltageCurrentOrder parse_mc_vi_order(
    std::string_view s);  // voltage_first | current_first | auto
motinova::McAnswerId parse_mc_answer_id(std::string_view s);  // 0x713 | 0x716 | 0x710 | auto
motinova::WheelSizeUnit parse_wheel_size_unit(
    std::string_view s);  // circumference_cm | diameter_cm | diameter_inch
motinova::WheelAdjustUnit parse_wheel_adjust_unit(std::string_view s);  // cm | mm
// These set one name and return "" or say why the input is refused (shared with the flags).
std::string set_fault_name(motinova::DecodeOptions& p, motinova::FaultSource source,
                           std::string_view bit, std::string_view name);  // U6/U18/U20/U22
std::string set_assist_name(motinova::DecodeOptions& p, std::string_view value,
                            std::string_view name);  // U7: "0x33", "smart"
std::string set_pack_stats_counter_order(motinova::DecodeOptions& p,
                                         const std::vector<std::string>& names);  // U17

}  // namespace fleetgw::config
