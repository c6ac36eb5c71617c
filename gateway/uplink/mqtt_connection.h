// One way to build a Paho MQTT connection: the broker URI spelling, the connect options and the
// TLS options, shared by the uplink, `fleetgw watch` and `fleetgw command`.
//
// Contract:
//  * normalise_broker_uri() maps mqtt:// to tcp:// and mqtts:// to ssl:// (Paho's spellings) and
//    leaves every other URI unchanged. uses_tls() is true for ssl://, mqtts:// and wss://.
//  * make_connect_options() never weakens TLS: whenever the URI uses TLS, the server certificate
//    chain is verified (against tls.ca_file, or the system trust store when it is empty) and,
//    unless tls.verify_server_name is false, the host name too. A TLS URI without a TlsConfig
//    gets the defaults (system trust store, full verification). TLS 1.2 is the minimum.
//  * The protocol of `settings.protocol` (3.1.1 unless asked for 5: the operator tools that do
//    not choose stay as they were). Under MQTT 5 `clean_session` is sent as clean start and a
//    persistent session asks for `session_expiry`; make_client() must create the client with the
//    same protocol (Paho C refuses an MQTT 5 connect on a client created for 3.1.1).
//  * No automatic reconnect (callers own their retry policy), credentials only when non-empty.
//    Nothing here logs; the password is only copied into the options.
//  * connack_reason() names an MQTT 3.1.1 CONNACK refusal code (1..5); empty for other codes.
#pragma once

#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include <mqtt/async_client.h>
#include <mqtt/connect_options.h>

#include "gateway/uplink/uplink_config.h"

namespace fleetgw::uplink {

struct ConnectionSettings {
  std::string broker_uri;  // as configured; normalised by make_connect_options' callers
  std::optional<TlsConfig> tls;
  std::string username;
  std::string password;
  std::chrono::seconds keep_alive{30};
  std::chrono::seconds connect_timeout{10};
  // false = persistent session (the uplink); true for the one-shot operator tools.
  bool clean_session = true;
  // Paho's own limit of unacknowledged publishes (0 = Paho's default).
  int max_inflight = 0;
  MqttProtocol protocol = MqttProtocol::kV311;
  // MQTT 5 only: session expiry interval sent with a persistent session (clean_session false).
  std::chrono::seconds session_expiry{0};
};

std::string normalise_broker_uri(std::string_view uri);
bool uses_tls(std::string_view uri);

// The options for `settings`; add a will message or other per-tool settings afterwards.
mqtt::connect_options make_connect_options(const ConnectionSettings& settings);

// A client for `uri` able to speak `protocol`.
std::unique_ptr<mqtt::async_client> make_client(const std::string& uri,
                                                const std::string& client_id,
                                                MqttProtocol protocol);

std::string_view connack_reason(int code);

}  // namespace fleetgw::uplink
