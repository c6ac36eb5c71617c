// Routes protobuf's own log messages into spdlog, rate limited.
//
// Why: protobuf prints one stderr line for every invalid UTF-8 string it meets while parsing or
// serialising ("String field ... contains invalid UTF-8 data ..."), so an attacker who can
// publish on the command topic could flood the log with lines the gateway does not control.
//
// Contract:
//  * ProtobufLogRoute installs, on construction, one handler with
//    google::protobuf::SetLogHandler; the fleetgw binary makes exactly one, first thing in
//    main(). Messages go to the spdlog default logger (as it is when the first message arrives,
//    i.e. after the configured logging is set up) through storage::RateLimitedLog: a repeated
//    identical message is written once per `window` with the count of repetitions.
//    Warnings and errors are prefixed "protobuf: " and quoted through the untrusted-text rule
//    (protobuf may quote received bytes); INFO messages are dropped.
//  * Destruction restores protobuf's default handler and writes one line with the number of
//    repetitions still unreported, so a burst at the end of a run is counted too.
//  * The handler may be called from any thread (Paho callback threads parse payloads too): its
//    state is behind a mutex. It is the one piece of process-wide state the route owns, because
//    protobuf's handler is a plain function pointer.
#pragma once

#include <chrono>

namespace fleetgw::cli {

class ProtobufLogRoute {
 public:
  explicit ProtobufLogRoute(std::chrono::steady_clock::duration window = std::chrono::seconds(10));
  ~ProtobufLogRoute();
  ProtobufLogRoute(const ProtobufLogRoute&) = delete;
  ProtobufLogRoute& operator=(const ProtobufLogRoute&) = delete;
};

}  // namespace fleetgw::cli
