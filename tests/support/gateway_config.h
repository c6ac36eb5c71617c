// Test support: the TOML configuration of a `fleetgw run` under test, built key by key, so each
// test states only the settings it is about and the common ones exist once.
//
// Contract:
//  * GatewayConfig(vehicle_id, store) starts with [vehicle] id, [log] level = "info",
//    [can] transport = "sim", [storage] path = store and [status] socket = "" (no status
//    socket). Sections come out in the order first named, keys in the order first set; setting
//    a key again replaces its value in place.
//  * set() takes a raw TOML value (number, boolean, array) as given; set_string() writes a TOML
//    basic string, escaping backslash, double quote and control characters, so any path stays
//    one string. add_line() appends a raw TOML line as given (e.g. the `ops = "..."` line
//    `fleetgw keygen` prints for [command.trusted_keys]).
//  * sim(), gnss(), mqtt() and geofence() set the keys of a simulated bike, of a gpsd on
//    127.0.0.1, of the uplink and of signed zone bundles; a test adds or overrides keys with
//    set().
//  * write() writes text() to `file` and returns `file`; std::runtime_error names a file that
//    cannot be written.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace fleetgw::testing {

class GatewayConfig {
 public:
  GatewayConfig(const std::string& vehicle_id, const std::filesystem::path& store);

  GatewayConfig& set(const std::string& section, const std::string& key,
                     const std::string& toml_value);
  GatewayConfig& set_string(const std::string& section, const std::string& key,
                            const std::string& value);
  GatewayConfig& add_line(const std::string& section, const std::string& toml_line);

  // [sim] scenario = <scenario>, speed = <speed> (the simulated bike's time factor, a ceiling),
  // lockstep = true (bus time never runs ahead of the gateway on a loaded machine).
  GatewayConfig& sim(const std::filesystem::path& scenario, double speed);
  // [gnss] enabled = true, gpsd = "127.0.0.1:<port>", reconnect_max_ms = 1000 (a test's gpsd
  // comes and goes: the gateway must find it again within a second).
  GatewayConfig& gnss(std::uint16_t gpsd_port);
  // [mqtt] enabled = true, uri = <uri>.
  GatewayConfig& mqtt(const std::string& uri);
  // [geofence] enabled = true, bundle_file = <bundle>, margin_m = 5 (the tests' zones are tens of
  // metres apart); the operator's `id = "<public key>"` line in [command.trusted_keys], as
  // bundles are signed with that key.
  GatewayConfig& geofence(const std::filesystem::path& bundle, const std::string& trusted_key_line);

  std::string text() const;
  std::filesystem::path write(const std::filesystem::path& file) const;

 private:
  struct Line {
    std::string key;  // empty for a raw line
    std::string text;
  };
  struct Section {
    std::string name;
    std::vector<Line> lines;
  };
  Section& section(const std::string& name);

  std::vector<Section> sections_;
};

// The usual `fleetgw run` of the service tests: the simulated bike (`scenario` at `speed`,
// lock-step, start_now = true), the uplink to `broker_uri`, a status socket at
// <dir>/status.sock, the store at <dir>/fleetgw.db and the operator's key `key_id` =
// `public_key_b64` trusted for commands. A test adds or overrides keys with set().
GatewayConfig service_config(const std::string& vehicle_id, const std::filesystem::path& dir,
                             const std::filesystem::path& scenario, double speed,
                             const std::string& broker_uri, const std::string& key_id,
                             const std::string& public_key_b64);

// `value` as a TOML basic string, quotes included.
std::string toml_string(const std::string& value);

}  // namespace fleetgw::testing
