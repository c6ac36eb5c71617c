// What fleetgw puts into MQTT 5 properties, and how it names MQTT 5 reason codes.
//
// Contract:
//  * envelope_properties(): the properties of every message the uplink publishes under MQTT 5
//    (records, status, vehicle state, the last will): content type kEnvelopeContentType and the
//    user property kSchemaProperty = kSchemaVersion, so a consumer knows what the payload is and
//    which fleetgw.v1 revision wrote it without decoding it. Nothing is added under 3.1.1.
//  * is_refusal(): true for an MQTT 5 reason code that means "not accepted" (0x80..0xFE, e.g.
//    0x87 not authorised from a broker ACL). Codes below 0x80 are successes (0x10 "no matching
//    subscribers" included).
//  * reason_text(): "0x87 Not authorized": the code in hex and Paho's name for it (never empty).
#pragma once

#include <string>
#include <string_view>

#include <mqtt/properties.h>

namespace fleetgw::uplink {

inline constexpr std::string_view kEnvelopeContentType =
    "application/x-protobuf; proto=fleetgw.v1.Envelope";
inline constexpr std::string_view kSchemaProperty = "schema";
// The revision of package fleetgw.v1 this build writes (docs/uplink.md lists what each added).
inline constexpr std::string_view kSchemaVersion = "1.4";
// User property of the last will: its will delay in seconds, so a consumer can date the loss.
inline constexpr std::string_view kWillDelayProperty = "will_delay_s";

mqtt::properties envelope_properties();

inline bool is_refusal(int reason_code) {
  // 0xFF is not an MQTT 5 code: Paho C++ uses it to mark 3.1.1 tokens (MQTTPP_V3_CODE).
  return reason_code >= 0x80 && reason_code < 0xFF;
}

std::string reason_text(int reason_code);

}  // namespace fleetgw::uplink
