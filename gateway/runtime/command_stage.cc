#include "gateway/runtime/command_stage.h"

#include <spdlog/spdlog.h>

namespace fleetgw::runtime {

bool CommandStage::due() const {
  return !payloads.empty() || !busy.empty() || !revocations.empty() || !handed.empty() ||
         service_.writes_pending();
}

std::optional<EngineTime> CommandStage::next_deadline() const {
  if (due()) return engine_.now();
  const auto at = service_.next_due(clock_.latest());
  if (!at) return std::nullopt;
  return clock_.to_engine(*at);
}

StageRun CommandStage::run(EngineTime) {
  for (const auto& h : std::exchange(handed, {})) service_.unstored_handed(h.command_id, h.handed);
  if (!payloads.empty() || !busy.empty()) {
    // A command acts on the bus as it is now, not as of the simulator's last batch.
    if (sim_) {
      sim_->flush();
      if (engine_.stopped()) return {};  // the pipeline answers what is left (shutting_down)
    }
    for (const auto& payload : std::exchange(payloads, {})) {
      ++handled_;
      const auto d = service_.on_payload(payload, clock_.now());
      spdlog::info("command received: {}", command::disposition_name(d));
    }
    // What the uplink's full queue could not take: each answered `busy`, none silently lost.
    for (const auto& b : std::exchange(busy, {})) {
      ++handled_;
      service_.answer_busy(b.command_id, b.command_sha256, clock_.now());
    }
  }
  for (const auto& payload : std::exchange(revocations, {})) {
    service_.on_revocations({reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()},
                            engine_.env().wall_now());
  }
  // The due work: results concluded on the bus (inside the transport's read handler) written
  // now, the journal retry, purging, the captured records.
  const motinova::Micros bus = clock_.latest();
  if (const auto at = service_.next_due(bus); at && *at <= bus) service_.run(bus);
  stored += service_.take_stored();
  for (auto& u : service_.take_unstored()) unstored.push_back(std::move(u));
  return {.produced = stored + unstored.size(), .status = {}};
}

}  // namespace fleetgw::runtime
