// Configuration of the MQTT uplink, and its validation.
//
// Contract: validate() throws std::invalid_argument naming the offending field when a value is
// unusable or insecure (e.g. credentials over plain tcp:// unless explicitly allowed, a vehicle
// id that is not a single topic level). Messages never contain the password, and URIs are quoted
// without user information. Defaults are the production defaults: QoS 1, persistent session,
// 30 s keep-alive, TLS server verification on whenever TLS is used.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace fleetgw::uplink {

struct TlsConfig {
  // CA bundle (PEM) the broker certificate must chain to. Empty = the system trust store.
  std::string ca_file;
  // Client certificate and private key (PEM) for mutual TLS; both or neither.
  std::string cert_file;
  std::string key_file;
  // Check that the broker certificate names the host in the URI. Turning this off is for lab
  // brokers only; it is logged as a warning on every connect.
  bool verify_server_name = true;
};

// The MQTT protocol version the uplink speaks (docs/uplink.md, "MQTT 5").
enum class MqttProtocol {
  kV311,  // MQTT 3.1.1: the fallback for brokers without MQTT 5 (no reason codes on PUBACK)
  kV5,    // MQTT 5: refused publishes are seen, properties on every message
};
// "5" or "3.1.1", the spelling of [mqtt] protocol.
std::string_view to_string(MqttProtocol protocol);

struct UplinkConfig {
  // tcp://host:port or ssl://host:port (mqtts:// is accepted as ssl://). No user information.
  std::string broker_uri;
  // Vehicle identifier: MQTT client id and topic level. [A-Za-z0-9._-], 1..64 characters.
  std::string vehicle_id;
  // Topic prefix before /<vehicle_id>/... ; no wildcards, no leading or trailing '/'.
  std::string topic_prefix = "fleet/v1";
  // Reported in every Envelope.
  std::string firmware_version;
  // Identifier of the store the outbox belongs to (storage::Store::store_id()), reported in every
  // Envelope except the last will; empty = not reported.
  std::string store_id;

  std::optional<TlsConfig> tls;  // required for ssl:// URIs
  std::string username;          // optional
  std::string password;          // optional; never logged
  // Credentials over an unencrypted connection are refused unless this is set (lab only).
  bool allow_plaintext_credentials = false;

  // TCP_NODELAY on the broker connection after every connect (see tcp_nodelay.h): a command
  // result leaves at once instead of waiting up to 40 ms behind its own PUBACK.
  bool tcp_nodelay = true;

  std::chrono::seconds keep_alive{30};
  std::chrono::seconds connect_timeout{10};
  MqttProtocol protocol = MqttProtocol::kV5;
  // MQTT 5 only (ignored under 3.1.1, where the session lasts until the next clean session):
  // how long the broker keeps the session (the cmd subscription, commands queued for the
  // vehicle, unacknowledged QoS 1 exchanges) after the connection ends. 0..4294967295 s
  // (0xFFFFFFFF = never expires).
  std::chrono::seconds session_expiry{86'400};
  // MQTT 5 only: the broker publishes the last will this long after it noticed the loss, and not
  // at all when the gateway reconnects within it (a short outage does not flap to OFFLINE).
  std::chrono::seconds will_delay{15};
  // Reconnect back-off: the n-th consecutive failure waits a random time in
  // [d/2, d] with d = min(reconnect_max, reconnect_min * 2^n). The same bounds pace the retries
  // of publishes the broker refused (MQTT 5 reason code >= 0x80).
  std::chrono::milliseconds reconnect_min{1000};
  std::chrono::milliseconds reconnect_max{120'000};
  std::uint64_t jitter_seed = 0;  // 0 = seed from std::random_device

  // Publishes (MQTT messages) sent and not yet acknowledged by the broker, at most.
  std::size_t max_in_flight = 64;
  // QoS of all records except live telemetry.
  int qos = 1;
  // QoS of telemetry batches whose newest sample is younger than live_telemetry_max_age.
  // Telemetry older than that (a backlog after an outage) always goes with `qos`. With QoS 0 a
  // batch counts as delivered once written to the socket, so it can be lost on a connection drop.
  int live_telemetry_qos = 0;
  std::chrono::milliseconds live_telemetry_max_age{10'000};
  // A TelemetryBatch is sent when it holds this many samples or bytes, or when its oldest
  // sample has waited telemetry_batch_max_delay.
  std::size_t telemetry_batch_max_samples = 256;
  std::size_t telemetry_batch_max_bytes = 16 * 1024;
  std::chrono::milliseconds telemetry_batch_max_delay{1000};
  // A QoS 1 publish interrupted by a connection loss is normally completed by Paho after the
  // reconnect; if it is still open this long into the new connection its records are sent again.
  std::chrono::milliseconds resend_after{20'000};
  // Upper bound on the payload bytes fetched from the outbox per poll.
  std::size_t max_fetch_bytes = 1024 * 1024;

  // Commands larger than this are dropped (and logged) without being parsed.
  std::size_t max_command_bytes = 4096;
  // Commands waiting for poll() at most; more are dropped (a flood cannot exhaust memory).
  std::size_t max_queued_commands = 16;

  // Zone bundles (docs/location.md "Bundles over MQTT"): the retained topics subscribed to for
  // fleetgw.v1.SignedZoneBundle payloads (empty = none, geofences off). Payloads larger than
  // max_zone_bundle_bytes are refused on Paho's thread before anything is copied or parsed; at
  // most max_queued_zone_bundles wait for take_zone_bundles(), more are dropped (a retained
  // bundle comes again at the next connect).
  std::vector<std::string> zone_topics;
  std::size_t max_zone_bundle_bytes = 1024 * 1024;
  std::size_t max_queued_zone_bundles = 4;

  void validate() const;
};

// The URI with any user information removed, safe for logs and error messages.
std::string redact_uri(std::string_view uri);

}  // namespace fleetgw::uplink
