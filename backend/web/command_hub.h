// The console's link to the broker for commands (issue 28): publishes signed commands on
// <prefix>/<vehicle>/cmd and takes their results from <prefix>/+/cmd/result.
//
// Contract:
//  * The constructor connects (MQTT 5, TLS options as for fleetgw ingest) and subscribes to
//    <prefix>/+/cmd/result at QoS 1; std::runtime_error names the broker when it cannot be
//    reached at start. It then reconnects by itself (and subscribes again).
//  * send() records the command in console_commands (who, from where, what, the digests)
//    BEFORE publishing it at QoS 1 (so a fast result finds its row), and waits up to 5 s for
//    the broker's acknowledgement; std::runtime_error when the broker did not take it (the row
//    then holds result `not_published`).
//  * A result is accepted for a row only when its topic's vehicle is the row's, and its
//    command_id and command_sha256 are the row's (an authentic command's answer) or its
//    payload_sha256 is that of the published SignedCommand (the bike could not authenticate
//    it: unknown_key, signature_invalid, ...); the first accepted result stands. Results of
//    commands this console did not send are ignored. Every accepted result is audited
//    (action `command_result`) and announced through `on_result` (on Paho's thread).
//  * Several instances behind a load balancer each receive every result; the row's
//    "result IS NULL" condition makes exactly one of them store it.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "backend/common/pg.h"
#include "backend/web/auth.h"
#include "backend/web/command_signer.h"
#include "backend/web/serve_options.h"

namespace fleetgw::web {

struct CommandOrigin {
  std::string operator_name;
  std::string address;
  std::string batch_id;  // several vehicles at once: one id for the batch ("" for one)
};

class CommandHub {
 public:
  CommandHub(const ServeOptions& o, PgPool& pool, Auth& auth, std::function<void()> on_result);
  ~CommandHub();
  CommandHub(const CommandHub&) = delete;
  CommandHub& operator=(const CommandHub&) = delete;

  void send(const CommandRequest& r, const std::string& vehicle_id, const std::string& key_id,
            std::optional<std::uint64_t> delegation_serial, const SignedCommandBytes& cmd,
            const CommandOrigin& origin);
  bool connected() const;
  // Retained documents (revocation lists, zone bundles: issue 28) at QoS 1 on each topic, all
  // published before any is waited for; std::runtime_error names the first topic the broker
  // did not acknowledge within 10 s in all.
  void publish_retained(const std::vector<std::string>& topics, const std::string& payload);

 private:
  std::string o_topic(const std::string& vehicle_id) const;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Short result names of CommandResultCode: succeeded, failed, timeout, rejected.
std::string command_result_name(int code);

}  // namespace fleetgw::web
