#include "gateway/uplink/uplink_config.h"

#include <unistd.h>

#include <stdexcept>

#include "gateway/uplink/topics.h"
#include "gateway/uplink/uplink_config_check.h"

namespace fleetgw::uplink {

namespace {

[[noreturn]] void fail(std::string_view field, std::string_view why) {
  throw std::invalid_argument("uplink." + std::string(field) + ": " + std::string(why));
}

void require_readable(std::string_view field, const std::string& path) {
  if (::access(path.c_str(), R_OK) != 0) fail(field, "cannot read file '" + path + "'");
}

}  // namespace

std::string_view to_string(MqttProtocol protocol) {
  return protocol == MqttProtocol::kV5 ? "5" : "3.1.1";
}

std::string redact_uri(std::string_view uri) {
  const auto scheme_end = uri.find("://");
  const std::size_t authority = scheme_end == std::string_view::npos ? 0 : scheme_end + 3;
  const auto path_start = uri.find('/', authority);
  const auto at = uri.rfind('@', path_start == std::string_view::npos ? uri.size() : path_start);
  if (at == std::string_view::npos || at < authority) return std::string(uri);
  return std::string(uri.substr(0, authority)) + "***@" + std::string(uri.substr(at + 1));
}

void UplinkConfig::validate() const {
  if (auto p = check_uplink_config(*this); !p.empty()) throw std::invalid_argument(describe(p[0]));
  const std::string safe_uri = redact_uri(broker_uri);
  const bool is_ssl = broker_uri.starts_with("ssl://") || broker_uri.starts_with("mqtts://");
  const bool is_tcp = broker_uri.starts_with("tcp://") || broker_uri.starts_with("mqtt://");
  if (!is_ssl && !is_tcp) {
    fail("broker_uri", "'" + safe_uri + "' must start with tcp:// or ssl://");
  }
  if (safe_uri != broker_uri) {
    fail("broker_uri",
         "'" + safe_uri + "' contains user information; set uplink.username/password instead");
  }
  const auto host_port = std::string_view(broker_uri).substr(broker_uri.find("://") + 3);
  if (host_port.empty() || host_port.find(':') == std::string_view::npos) {
    fail("broker_uri", "'" + safe_uri + "' needs host:port");
  }
  if (!is_valid_vehicle_id(vehicle_id)) {
    fail("vehicle_id", "'" + vehicle_id + "' must be 1..64 characters of [A-Za-z0-9._-]");
  }
  if (!is_valid_topic_prefix(topic_prefix)) {
    fail("topic_prefix", "'" + topic_prefix +
                             "' must be non-empty, without '+', '#', empty levels or "
                             "leading/trailing '/'");
  }
  if (is_ssl && !tls) fail("tls", "an ssl:// broker_uri needs a [tls] section");
  if (is_tcp && tls) fail("tls", "TLS is configured but broker_uri is tcp://; use ssl://");
  if (tls) {
    if (!tls->ca_file.empty()) require_readable("tls.ca_file", tls->ca_file);
    if (tls->cert_file.empty() != tls->key_file.empty()) {
      fail("tls", "cert_file and key_file must be given together");
    }
    if (!tls->cert_file.empty()) {
      require_readable("tls.cert_file", tls->cert_file);
      require_readable("tls.key_file", tls->key_file);
    }
  }
  if (!password.empty() && username.empty()) fail("password", "given without a username");
  if (is_tcp && (!username.empty() || !password.empty()) && !allow_plaintext_credentials) {
    fail("username",
         "credentials over unencrypted tcp:// are refused; use ssl:// (or set "
         "allow_plaintext_credentials for a lab broker)");
  }
  if (keep_alive.count() < 0 || keep_alive.count() > 65535) {
    fail("keep_alive", "must be 0..65535 s");
  }
  if (connect_timeout.count() <= 0) fail("connect_timeout", "must be positive");
  if (reconnect_min.count() <= 0) fail("reconnect_min", "must be positive");
  if (reconnect_max < reconnect_min) fail("reconnect_max", "must be >= reconnect_min");
  if (max_in_flight == 0 || max_in_flight > 65000) fail("max_in_flight", "must be 1..65000");
  if (qos < 0 || qos > 1) fail("qos", "must be 0 or 1");
  if (live_telemetry_qos < 0 || live_telemetry_qos > 1) {
    fail("live_telemetry_qos", "must be 0 or 1");
  }
  if (telemetry_batch_max_samples == 0) fail("telemetry_batch_max_samples", "must be >= 1");
  if (telemetry_batch_max_bytes < 64) fail("telemetry_batch_max_bytes", "must be >= 64");
  if (telemetry_batch_max_delay.count() < 0) fail("telemetry_batch_max_delay", "must be >= 0");
  if (resend_after.count() <= 0) fail("resend_after", "must be positive");
  if (max_fetch_bytes == 0) fail("max_fetch_bytes", "must be positive");
  if (max_command_bytes == 0) fail("max_command_bytes", "must be positive");
  if (max_queued_commands == 0) fail("max_queued_commands", "must be positive");
  for (const auto& t : zone_topics) {
    // A subscription, but never a filter: one bundle source is one exact topic.
    if (!is_valid_topic_prefix(t)) {
      fail("zone_topics", "'" + t +
                              "' must be one topic name: non-empty, without '+', '#', empty "
                              "levels or leading/trailing '/'");
    }
    if (t == Topics(topic_prefix, vehicle_id).cmd)
      fail("zone_topics", "'" + t + "' is the cmd topic");
  }
  if (!zone_topics.empty() && max_zone_bundle_bytes == 0) {
    fail("max_zone_bundle_bytes", "must be positive");
  }
  if (!zone_topics.empty() && max_queued_zone_bundles == 0) {
    fail("max_queued_zone_bundles", "must be positive");
  }
}

}  // namespace fleetgw::uplink
