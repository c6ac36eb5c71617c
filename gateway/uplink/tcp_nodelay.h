// TCP_NODELAY for the MQTT connection that Paho owns.
//
// Why: Paho C 1.3 creates its TCP socket itself and has no option for TCP_NODELAY. With Nagle's
// algorithm on, a small publish that follows one of our own small segments (a command result
// right after the command's PUBACK) waits until the broker acknowledges the first, and Linux
// delays that ACK by up to 40 ms: the remote-command round trip grows from milliseconds to
// ~90 ms at p99. MQTT packets are whole messages written in one call, so Nagle buys nothing.
//
// Contract: enable_tcp_nodelay_to_port(port) sets TCP_NODELAY on every TCP socket of this
// process whose peer port is `port` and returns how many it found (0 = none; the caller decides
// whether that is worth a log line). Best effort, never throws, no allocation-heavy work: it
// walks /proc/self/fd once. Call it after the connection is established (Paho's connected
// callback); a reconnect creates a new socket, so call it after every connect.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

namespace fleetgw::uplink {

// The TCP port of a broker URI: tcp://h:p, ssl://h:p, mqtt://, mqtts://, ws://, wss://;
// IPv6 literals in brackets. Scheme defaults (1883, 8883, 80, 443) when no port is given.
// nullopt for a URI that names no TCP endpoint.
std::optional<std::uint16_t> broker_port(std::string_view uri);

int enable_tcp_nodelay_to_port(std::uint16_t port);

}  // namespace fleetgw::uplink
