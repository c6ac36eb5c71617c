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
//  * MQTT 3.1.1, no automatic reconnect (callers own their retry policy), credentials only when
//    non-empty. Nothing here logs; the password is only copied into the options.
//  * connack_reason() names an MQTT 3.1.1 CONNACK refusal code (1..5); empty for other codes.
#pragma once

#include <chrono>
#include <optional>
#include <string>
#include <string_view>

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
};

std::string normalise_broker_uri(std::string_view uri);
bool uses_tls(std::string_view uri);

// The options for `settings`; add a will message or other per-tool settings afterwards.
mqtt::connect_options make_connect_options(const ConnectionSettings& settings);

std::string_view connack_reason(int code);

}  // namespace fleetgw::uplink
