#include "gateway/uplink/uplink_config_check.h"

#include <unistd.h>

#include <cstdint>
#include <map>

#include "gateway/uplink/topics.h"

namespace fleetgw::uplink {
namespace {

// Where each field comes from in fleetgw.toml (runtime::make_uplink_config).
std::string config_key_of(const std::string& field) {
  static const std::map<std::string, std::string, std::less<>> keys{
      {"broker_uri", "mqtt.uri"},
      {"vehicle_id", "vehicle.id"},
      {"topic_prefix", "mqtt.topic_prefix"},
      {"tls", "mqtt.uri"},
      {"tls.ca_file", "mqtt.ca_file"},
      {"tls.cert_file", "mqtt.cert_file"},
      {"tls.key_file", "mqtt.key_file"},
      {"username", "mqtt.username"},
      {"password", "mqtt.password"},
      {"keep_alive", "mqtt.keepalive_s"},
      {"reconnect_min", "mqtt.reconnect_min_ms"},
      {"reconnect_max", "mqtt.reconnect_max_ms"},
      {"max_in_flight", "mqtt.max_inflight"},
      {"live_telemetry_qos", "mqtt.telemetry_qos"},
      {"telemetry_batch_max_samples", "mqtt.batch_max_samples"},
      {"telemetry_batch_max_delay", "mqtt.batch_max_ms"},
      {"protocol", "mqtt.protocol"},
      {"session_expiry", "mqtt.session_expiry_s"},
      {"will_delay", "mqtt.will_delay_s"},
  };
  const auto it = keys.find(field);
  return it != keys.end() ? it->second : "uplink." + field;
}

}  // namespace

std::vector<UplinkConfigProblem> check_uplink_config(const UplinkConfig& c) {
  std::vector<UplinkConfigProblem> out;
  auto fail = [&](std::string field, std::string message) {
    std::string key = config_key_of(field);
    out.push_back({std::move(field), std::move(key), std::move(message)});
  };
  auto require_readable = [&](const char* field, const std::string& path) {
    if (::access(path.c_str(), R_OK) != 0) fail(field, "cannot read file '" + path + "'");
  };

  const std::string safe_uri = redact_uri(c.broker_uri);
  const bool is_ssl = c.broker_uri.starts_with("ssl://") || c.broker_uri.starts_with("mqtts://");
  const bool is_tcp = c.broker_uri.starts_with("tcp://") || c.broker_uri.starts_with("mqtt://");
  if (!is_ssl && !is_tcp) {
    fail("broker_uri", "'" + safe_uri + "' must start with tcp:// or ssl://");
  }
  if (safe_uri != c.broker_uri) {
    fail("broker_uri", "'" + safe_uri +
                           "' contains user information; set mqtt.username and mqtt.password "
                           "instead (with an ssl:// URI)");
  }
  if (is_ssl || is_tcp) {
    const auto host_port = std::string_view(c.broker_uri).substr(c.broker_uri.find("://") + 3);
    if (host_port.empty() || host_port.find(':') == std::string_view::npos) {
      fail("broker_uri", "'" + safe_uri + "' needs host:port");
    }
  }
  if (!is_valid_vehicle_id(c.vehicle_id)) {
    fail("vehicle_id", "'" + c.vehicle_id + "' must be 1..64 characters of [A-Za-z0-9._-]");
  }
  if (!is_valid_topic_prefix(c.topic_prefix)) {
    fail("topic_prefix", "'" + c.topic_prefix +
                             "' must be non-empty, without '+', '#', empty levels or "
                             "leading/trailing '/'");
  }
  if (is_ssl && !c.tls) fail("tls", "an ssl:// URI needs TLS settings");
  if (is_tcp && c.tls) fail("tls", "TLS is configured but the URI is tcp://; use ssl://");
  if (c.tls) {
    if (!c.tls->ca_file.empty()) require_readable("tls.ca_file", c.tls->ca_file);
    if (c.tls->cert_file.empty() != c.tls->key_file.empty()) {
      fail(c.tls->cert_file.empty() ? "tls.cert_file" : "tls.key_file",
           "mqtt.cert_file and mqtt.key_file must be given together (mutual TLS)");
    }
    if (!c.tls->cert_file.empty()) require_readable("tls.cert_file", c.tls->cert_file);
    if (!c.tls->key_file.empty()) require_readable("tls.key_file", c.tls->key_file);
  }
  if (!c.password.empty() && c.username.empty()) {
    fail("password", "mqtt.password is given without mqtt.username");
  }
  if (is_tcp && (!c.username.empty() || !c.password.empty()) && !c.allow_plaintext_credentials) {
    fail(c.username.empty() ? "password" : "username",
         "credentials over unencrypted tcp:// are refused: use an ssl:// mqtt.uri (with "
         "mqtt.ca_file), or remove mqtt.username and mqtt.password");
  }
  if (c.keep_alive.count() < 0 || c.keep_alive.count() > 65535) {
    fail("keep_alive", "must be 0..65535 s");
  }
  if (c.connect_timeout.count() <= 0) fail("connect_timeout", "must be positive");
  if (c.reconnect_min.count() <= 0) fail("reconnect_min", "must be positive");
  if (c.reconnect_max < c.reconnect_min) {
    fail("reconnect_max", "mqtt.reconnect_max_ms must be >= mqtt.reconnect_min_ms");
  }
  if (c.max_in_flight == 0 || c.max_in_flight > 65000) fail("max_in_flight", "must be 1..65000");
  if (c.qos < 0 || c.qos > 1) fail("qos", "must be 0 or 1");
  if (c.live_telemetry_qos < 0 || c.live_telemetry_qos > 1) {
    fail("live_telemetry_qos", "must be 0 or 1");
  }
  if (c.telemetry_batch_max_samples == 0) fail("telemetry_batch_max_samples", "must be >= 1");
  if (c.telemetry_batch_max_bytes < 64) fail("telemetry_batch_max_bytes", "must be >= 64");
  if (c.telemetry_batch_max_delay.count() < 0) fail("telemetry_batch_max_delay", "must be >= 0");
  if (c.resend_after.count() <= 0) fail("resend_after", "must be positive");
  if (c.max_fetch_bytes == 0) fail("max_fetch_bytes", "must be positive");
  if (c.max_command_bytes == 0) fail("max_command_bytes", "must be positive");
  if (c.max_queued_commands == 0) fail("max_queued_commands", "must be positive");
  // MQTT 5 carries both as four-byte intervals.
  constexpr std::int64_t kMaxInterval = 0xFFFF'FFFF;
  if (c.session_expiry.count() < 0 || c.session_expiry.count() > kMaxInterval) {
    fail("session_expiry", "must be 0..4294967295 s");
  }
  if (c.will_delay.count() < 0 || c.will_delay.count() > kMaxInterval) {
    fail("will_delay", "must be 0..4294967295 s");
  }
  return out;
}

std::string describe(const UplinkConfigProblem& p) {
  const std::string field = "uplink." + p.field;
  if (p.config_key == field) return field + ": " + p.message;
  return p.config_key + " (" + field + "): " + p.message;
}

}  // namespace fleetgw::uplink
