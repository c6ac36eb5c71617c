// Why a connection to the broker failed, in words a technician can act on.
//
// Why: Paho reports every failed TCP or TLS connect as "rc -1 (Failure)": a wrong CA, a wrong
// host name, a stopped broker and a network outage look the same. After a failed attempt the
// uplink repeats the same steps itself, off its own thread, and names the first that fails.
//
// Contract:
//  * diagnose_connect() is blocking (each step bounded by `timeout`), allocation-light, never
//    throws, and sends nothing but a TLS handshake (no MQTT packet): the broker sees a connection
//    that closes after the handshake.
//  * Reasons (stable prefixes, matched by `fleetgw status` users and tests):
//      "host not found (...)", "connection refused", "unreachable (...)",
//      "TLS: certificate verify failed (<OpenSSL verify reason>)", e.g. "(certificate has
//      expired)" or "(unable to get local issuer certificate)", "TLS: host name mismatch",
//      "TLS: handshake failed (...)", "TLS: cannot load ... (...)".
//    An empty reason means every step succeeded: the cause lies beyond TLS (the broker closed the
//    connection, an MQTT-level refusal...).
//  * is_tls_failure() is true for reasons starting with "TLS:".
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "gateway/uplink/uplink_config.h"

namespace fleetgw::uplink {

struct ProbeTarget {
  std::string host;
  std::uint16_t port = 0;
  std::optional<TlsConfig> tls;  // set for TLS URIs
};

// The host and port of a broker URI (tcp://, ssl://, mqtt://, mqtts://); nullopt otherwise.
std::optional<ProbeTarget> probe_target(std::string_view broker_uri,
                                        const std::optional<TlsConfig>& tls);

std::string diagnose_connect(const ProbeTarget& target, std::chrono::milliseconds timeout);

bool is_tls_failure(std::string_view reason);

}  // namespace fleetgw::uplink
