#include "gateway/uplink/mqtt_connection.h"

#include <mqtt/ssl_options.h>

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
  opts.set_mqtt_version(MQTTVERSION_3_1_1);
  opts.set_clean_session(s.clean_session);
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

std::string_view connack_reason(int code) {
  switch (code) {
    case 1:
      return "refused by the broker: unacceptable protocol version";
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
