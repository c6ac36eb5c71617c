// Stage: the one contract between the engine (`fleetgw run`'s event loop) and each part of the
// bike's data road -- the CAN transport, the core (reassembly, decode, node), the recorder
// (trackers -> SQLite), the command service, the uplink, GNSS, zones, parked mode.
//
// Contract:
//  * next_deadline(): the earliest engine time at which run() has due work, in the one time type
//    of the engine (Env::steady_now()); nullopt when nothing is scheduled and the stage will only
//    have work after new input (it then signals, see below). A stage on the bus timeline converts
//    its bus deadline through the engine's BusClock, never by hand.
//  * run(now): does the work that is due at `now` and returns what happened. It never calls
//    another stage: what it produced (records, commands, results, frames to send) waits in the
//    stage's own typed outputs until the engine moves it. It may be called early (nothing due:
//    it returns at once) and must be cheap then.
//  * Errors: a failed step is reported in StageRun::status (a Status, env/status.h: its code and
//    the stage's message); the stage keeps its data and the ENGINE decides when to retry, with
//    its one back-off (runtime/backoff.h). Stages do not keep retry timers of their own.
//  * Input arriving on another thread (Paho, gpsd) only marks the stage as signalled through
//    the engine's wake-up; the stage's state changes on the engine's thread, in run().
//  * Stages are never re-entered: the engine does not call run() of a stage inside run() of
//    any stage.
#pragma once

#include <cstddef>
#include <optional>
#include <string_view>

#include "env/env.h"
#include "env/status.h"

namespace fleetgw::runtime {

using EngineTime = Env::SteadyTime;

struct StageRun {
  std::size_t produced = 0;  // items now waiting in the stage's outputs (0: nothing new)
  Status status;             // not ok: the step failed; data kept; the engine backs off
  bool ok() const { return status.ok(); }
};

class Stage {
 public:
  virtual ~Stage() = default;
  virtual std::string_view name() const = 0;
  virtual std::optional<EngineTime> next_deadline() const = 0;
  virtual StageRun run(EngineTime now) = 0;
};

}  // namespace fleetgw::runtime
