// `fleetgw keys publish-revocations` (keys_tool.h): the root's list, retained, on each vehicle's
// revocations topic. A separate file: the only part of the keys tool that speaks MQTT.
#include <mqtt/async_client.h>

#include <fstream>
#include <iostream>
#include <iterator>

#include "fleetgw/v1/keys.pb.h"
#include "gateway/command/ed25519.h"
#include "gateway/command/signing.h"
#include "gateway/tools/operator/keys_tool.h"
#include "gateway/uplink/mqtt_connection.h"

namespace fleetgw::tools {

int run_keys_publish_revocations(const KeysPublishOptions& o, std::ostream& out,
                                 std::ostream& err) {
  auto usage = [&](const std::string& what) {
    err << "keys publish-revocations: " << what << '\n';
    return 2;
  };
  if (o.vehicles.empty()) return usage("--vehicle: at least one vehicle id");
  for (const auto& v : o.vehicles) {
    if (!command::is_valid_tool_id(v)) return usage("--vehicle: 1..64 of [A-Za-z0-9._-]");
  }
  if (o.broker.rfind("tcp://", 0) != 0 && o.broker.rfind("ssl://", 0) != 0) {
    return usage("--broker: tcp://host:port or ssl://host:port");
  }
  if (o.broker.find('@') != std::string::npos) {
    return usage("--broker: no credentials in the URI; use --username/--password");
  }
  const bool tls = uplink::uses_tls(o.broker);
  if (!tls && (!o.username.empty() || !o.password.empty()) && !o.allow_plaintext_credentials) {
    return usage("refusing to send credentials over plain tcp://; use ssl://");
  }
  if (o.topic_prefix.empty() || o.topic_prefix.find_first_of("#+") != std::string::npos) {
    return usage("--topic-prefix: no wildcards");
  }
  std::ifstream in(o.file, std::ios::binary);
  const std::string payload((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  v1::SignedRevocationList sl;
  v1::RevocationList list;
  if (payload.empty() || !sl.ParseFromString(payload) || !list.ParseFromString(sl.revocations()) ||
      list.version() == 0) {
    return usage(o.file.string() + " is not a signed revocation list (fleetgw keys revoke)");
  }
  try {
    const std::string uri = uplink::normalise_broker_uri(o.broker);
    const auto suffix = command::random_bytes(4);
    const auto client =
        uplink::make_client(uri,
                            "fleetgw-keys-" + std::to_string(suffix[0] << 8 | suffix[1]) + "-" +
                                std::to_string(suffix[2] << 8 | suffix[3]),
                            uplink::MqttProtocol::kV311);
    uplink::ConnectionSettings settings;
    settings.broker_uri = uri;
    if (tls) settings.tls = uplink::TlsConfig{o.ca_file, o.cert_file, o.key_file, true};
    settings.username = o.username;
    settings.password = o.password;
    settings.connect_timeout = o.timeout;
    if (!client->connect(uplink::make_connect_options(settings))->wait_for(o.timeout)) {
      err << "keys publish-revocations: no connection to " << o.broker << '\n';
      return 3;
    }
    for (const auto& v : o.vehicles) {
      const std::string topic = o.topic_prefix + "/" + v + "/revocations";
      // Retained: a gateway offline now gets it at its next connect.
      auto msg = mqtt::make_message(topic, payload.data(), payload.size(), 1, true);
      if (!client->publish(msg)->wait_for(o.timeout)) {
        err << "keys publish-revocations: " << topic << " not acknowledged in time\n";
        return 3;
      }
      out << "revocation list version " << list.version() << " retained on " << topic << '\n';
    }
    client->disconnect()->wait_for(std::chrono::seconds(2));
    return 0;
  } catch (const std::exception& e) {
    err << "keys publish-revocations: broker " << o.broker << ": " << e.what() << '\n';
    return 3;
  }
}

}  // namespace fleetgw::tools
