// CommandStage: the command service (gateway/command/command_service.h) as a stage of the engine
// (runtime/stage.h). The service stays free of the engine; this adapter gives it the contract.
//
// Contract:
//  * Inputs, filled by the routes: `payloads` (signed commands the uplink took), `busy` (those its
//    full queue could not take), `revocations` (payloads of the revocation-list topic). run()
//    hands them to the service in arrival order -- after flushing a simulated bus, so a command
//    acts on the bus as it is now -- and the service writes its journal and results there.
//  * The bus side of the service (CommandService::on_message/tick, the node's lock callbacks)
//    runs inside the core, that is inside the CAN transport's read handler, and never writes
//    SQLite: what it concluded waits in memory and run() writes it (next_deadline() is `now`
//    while it waits). The service's own schedule (the journal retry, purging, the captured
//    lifetime records) is on the bus timeline and reaches the engine through the BusClock.
//  * Outputs, taken by the route: `stored` (results queued in the outbox: the uplink publishes
//    them in the same settle), `unstored` (results the store refused: the route hands them to
//    the uplink stage, which publishes them directly; whether each reached MQTT comes back as
//    the input `handed`, which run() reports to the service: CommandService::unstored_handed()).
//  * run() never fails: a store the service cannot write is its own business (stored = false
//    answers, the journal retried), not the engine's back-off.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "gateway/can/paced_transport.h"
#include "gateway/command/command_service.h"
#include "gateway/runtime/bus_clock.h"
#include "gateway/runtime/engine.h"
#include "gateway/uplink/uplink.h"

namespace fleetgw::runtime {

class CommandStage final : public Stage {
 public:
  CommandStage(command::CommandService& service, const BusClock& clock, can::PacedTransport* sim,
               const Engine& engine)
      : service_(service), clock_(clock), sim_(sim), engine_(engine) {}
  std::string_view name() const override { return "commands"; }
  std::optional<EngineTime> next_deadline() const override;
  StageRun run(EngineTime now) override;

  // Something waits for run() right now (inputs, or results concluded on the bus).
  bool due() const;
  // Payloads handed to the service so far (busy answers included).
  std::uint64_t handled() const { return handled_; }

  // Inputs.
  std::vector<std::string> payloads;
  std::vector<uplink::BusyCommand> busy;
  std::vector<std::string> revocations;
  struct Handed {
    std::string command_id;
    bool handed = false;
  };
  std::vector<Handed> handed;

  // Outputs.
  std::size_t stored = 0;
  std::vector<command::UnstoredResult> unstored;

 private:
  command::CommandService& service_;
  const BusClock& clock_;
  can::PacedTransport* sim_;
  const Engine& engine_;
  std::uint64_t handled_ = 0;
};

}  // namespace fleetgw::runtime
