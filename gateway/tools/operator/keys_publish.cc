// `fleetgw keys publish-revocations` (keys_tool.h): the root's list, retained, on each vehicle's
// revocations topic. A separate file: the only part of the keys tool that speaks MQTT.
#include <mqtt/async_client.h>

#include <iostream>

#include "fleetgw/v1/keys.pb.h"
#include "gateway/command/ed25519.h"
#include "gateway/command/signing.h"
#include "gateway/tools/operator/keys_tool.h"
#include "gateway/tools/operator/operator_inputs.h"
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
  if (const auto error =
          broker_option_error(o.broker, o.username, o.password, o.allow_plaintext_credentials)) {
    return usage(*error);
  }
  const bool tls = uplink::uses_tls(o.broker);
  if (o.topic_prefix.empty() || o.topic_prefix.find_first_of("#+") != std::string::npos) {
    return usage("--topic-prefix: no wildcards");
  }
  constexpr std::string_view kWhat = "a signed revocation list (fleetgw keys revoke)";
  std::string error;
  const auto file = read_signed_file<v1::SignedRevocationList, v1::RevocationList>(
      o.file,
      [](const v1::SignedRevocationList& sl) -> const std::string& { return sl.revocations(); },
      kWhat, error);
  if (!file) return usage(error);
  const v1::RevocationList& list = file->document;
  if (list.version() == 0) return usage(o.file.string() + " is not " + std::string(kWhat));
  const std::string& payload = file->bytes;
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
