#include "gateway/uplink/mqtt_connection.h"

#include <mqtt/ssl_options.h>

#include <cstdint>

namespace fleetgw::uplink {

namespace {
bool starts_with(std::string_view s, std::string_view prefix) {
  return s.substr(0, prefix.size()) == prefix;
}
}  // namespace

std::string normalise_broker_uri(std::string_view uri) {
  if (starts_with(uri, "mqtts://")) return "ssl://" + std::string(uri.substr(8));
  if (starts_with(uri, "mqtt://")) return "tcp://" + std::string(uri.substr(7));
  return std::string(uri);
}

bool uses_tls(std::string_view uri) {
  return starts_with(uri, "ssl://") || starts_with(uri, "mqtts://") || starts_with(uri, "wss://");
}

mqtt::connect_options make_connect_options(const ConnectionSettings& s) {
  mqtt::connect_options opts;
  if (s.protocol == MqttProtocol::kV5) {
    opts.set_mqtt_version(MQTTVERSION_5);  // clears the 3.1.1 clean-session flag
    opts.set_clean_start(s.clean_session);
    if (!s.clean_session) {
      // Without it an MQTT 5 session ends with the connection, persistent or not.
      mqtt::properties props;
      props.add(mqtt::property(
          mqtt::property::SESSION_EXPIRY_INTERVAL,
          static_cast<std::int32_t>(static_cast<std::uint32_t>(s.session_expiry.count()))));
      opts.set_properties(std::move(props));
    }
  } else {
    opts.set_mqtt_version(MQTTVERSION_3_1_1);
    opts.set_clean_session(s.clean_session);
  }
  opts.set_keep_alive_interval(static_cast<int>(s.keep_alive.count()));
  opts.set_connect_timeout(static_cast<int>(std::max<std::int64_t>(1, s.connect_timeout.count())));
  opts.set_automatic_reconnect(false);
  if (s.max_inflight > 0) opts.set_max_inflight(s.max_inflight);
  if (!s.username.empty()) opts.set_user_name(s.username);
  if (!s.password.empty()) opts.set_password(s.password);
  if (s.tls || uses_tls(s.broker_uri)) {
    const TlsConfig tls = s.tls.value_or(TlsConfig{});
    mqtt::ssl_options ssl;
    if (!tls.ca_file.empty()) ssl.set_trust_store(tls.ca_file);
    if (!tls.cert_file.empty()) {
      ssl.set_key_store(tls.cert_file);
      ssl.set_private_key(tls.key_file);
    }
    ssl.set_enable_server_cert_auth(true);
    ssl.set_verify(tls.verify_server_name);
    ssl.set_ssl_version(MQTT_SSL_VERSION_TLS_1_2);
    // No ssl error handler here: Paho C++ keeps a pointer to the ssl_options object the handler
    // was set on, and that object does not survive the copies connect() makes. The uplink
    // diagnoses a failed handshake itself (connect_diagnosis.h).
    opts.set_ssl(std::move(ssl));
  }
  return opts;
}

std::unique_ptr<mqtt::async_client> make_client(const std::string& uri,
                                                const std::string& client_id,
                                                MqttProtocol protocol) {
  if (protocol == MqttProtocol::kV5) {
    return std::make_unique<mqtt::async_client>(uri, client_id,
                                                mqtt::create_options(MQTTVERSION_5));
  }
  return std::make_unique<mqtt::async_client>(uri, client_id);
}

std::string_view connack_reason(int code) {
  switch (code) {
    case 1:
      // A 3.1.1-only broker answers an MQTT 5 connect this way.
      return "refused by the broker: unacceptable protocol version (for a broker without MQTT 5, "
             "set [mqtt] protocol = \"3.1.1\")";
    case 2:
      return "refused by the broker: client identifier rejected";
    case 3:
      return "refused by the broker: server unavailable";
    case 4:
      return "not authorised: bad user name or password";
    case 5:
      return "not authorised";
    default:
      return {};
  }
}

}  // namespace fleetgw::uplink
