// The engine's retry schedule is the one Backoff of the gateway (env/backoff.h), kept under
// this name for the runtime's readers.
#pragma once

#include "env/backoff.h"
#include "gateway/runtime/stage.h"

namespace fleetgw::runtime {

using fleetgw::Backoff;

}  // namespace fleetgw::runtime
