// Test support for the ingest's end-to-end tests (one copy of what several of them build).
//
// Contract:
//  * fault_envelope(vehicle, seq, name) is a serialised Envelope carrying one MC fault record
//    `name` of (vehicle, "store-1", seq), created at a fixed time: the smallest record a worker
//    writes a row for (fault_events) and accounts a sequence for.
//  * count_or_minus_one(conninfo, sql) is the integer `sql` answers (first column, first row),
//    or -1 when the query fails (e.g. the worker has not made the schema yet), so tests can
//    poll it inside wait_until.
#pragma once

#include <cstdint>
#include <string>

#include "backend/common/pg.h"
#include "fleetgw/v1/envelope.pb.h"

namespace fleetgw::testing {

inline std::string fault_envelope(const std::string& vehicle, std::uint64_t seq,
                                  const std::string& name = "overheat") {
  v1::Envelope e;
  e.set_vehicle_id(vehicle);
  e.set_store_id("store-1");
  e.set_sequence(seq);
  e.set_created_at_us(1'700'000'000'000'000);
  e.mutable_fault()->set_node("mc");
  e.mutable_fault()->set_name(name);
  return e.SerializeAsString();
}

inline std::int64_t count_or_minus_one(const std::string& conninfo, const std::string& sql) {
  try {
    PgConnection c(conninfo);
    return c.exec(sql, "test query").int64(0, 0);
  } catch (const PgError&) {
    return -1;
  }
}

}  // namespace fleetgw::testing
