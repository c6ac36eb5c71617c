// MQTT 5 properties and reason-code names of the uplink; see mqtt5.h.
#include "gateway/uplink/mqtt5.h"

#include <MQTTReasonCodes.h>

#include <cstdio>

namespace fleetgw::uplink {

mqtt::properties envelope_properties() {
  mqtt::properties props;
  props.add(mqtt::property(mqtt::property::CONTENT_TYPE, std::string(kEnvelopeContentType)));
  props.add(mqtt::property(mqtt::property::USER_PROPERTY, std::string(kSchemaProperty),
                           std::string(kSchemaVersion)));
  return props;
}

std::string reason_text(int reason_code) {
  char hex[8];
  std::snprintf(hex, sizeof hex, "0x%02X", static_cast<unsigned>(reason_code) & 0xFFu);
  const char* name = MQTTReasonCode_toString(static_cast<MQTTReasonCodes>(reason_code));
  // Paho answers unknown codes with NULL (older releases) or "Unknown reason code".
  return std::string(hex) + " " + (name != nullptr ? name : "unknown reason code");
}

}  // namespace fleetgw::uplink
