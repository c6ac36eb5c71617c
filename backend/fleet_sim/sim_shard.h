// One process of fleetgw-fleet-sim: its share of the fleet on one epoll event loop, every
// vehicle a libmosquitto session driven through the external-loop API (mosquitto_socket,
// loop_read / loop_write / loop_misc, want_write). See fleet_sim_options.h for the contract.
//
// Why one loop per process and not a thread per session: 50,000 sessions on 2 cores. A session
// costs a socket and a few kB here; threads would cost a stack each and context switches per
// message. Why processes and not threads for several loops: the descriptor limit is per process
// (this machine's hard limit is 20,000), and a process is the simplest unit to stop or kill.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

#include "backend/fleet_sim/fleet_sim_options.h"

namespace fleetgw::fleet_sim {

struct ShardPlan {
  FleetSimOptions options;
  std::string host;
  int port = 1883;
  int shard = 0;   // this process's number
  int shards = 1;  // vehicle i (0-based in the fleet) belongs to shard i % shards
  int riding = 0;  // vehicles 0..riding-1 of the fleet ride
  int source_addresses = 0;
  std::int64_t start_us = 0;  // the fleet's start (µs since the epoch)
};

// Runs the shard until its duration ends or SIGINT/SIGTERM arrives (the caller blocks both
// before calling; the loop takes them through a signalfd) and returns its report (the fields of
// the fleet report, for this shard's vehicles).
nlohmann::json run_shard(const ShardPlan& plan);

// The wall clock in µs since the epoch: records' created_at_us and the fleet's start.
std::int64_t now_us();

}  // namespace fleetgw::fleet_sim
