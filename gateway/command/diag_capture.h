// DiagCapture (issue 29): the lifetime records -- MC 0x715/0xA230 and 0xAC10, pack 0x725/0x5028
// -- as last seen on the bus, whoever asked for them (the service dongle, the poller's 0x5400,
// a diagnostic read), so a technician can read the last one without a bus request
// (DiagnosticRead.last_captured).
//
// Contract:
//  * Single-threaded; fed every decoded message (on_message) and ticked (tick).
//  * Each record is kept in memory at once and written, at the next tick() (called from the
//    command service's run(), never from the frame handler), to the store's meta
//    table (`diag.captured.<message>` = "<heard wall µs> <data hex>") when its bytes changed, at
//    most once per `persist_interval` per record (the pack statistics arrive every minute and their
//    run time changes each time: a minute's write, not a write per frame) -- so a restart keeps
//    the last one, up to that interval old. A store failure is logged; the record stays in
//    memory and is written at a later tick.
//  * Restored from the store at construction; a stored line that does not parse is ignored
//    (logged).
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "motinova/can.h"
#include "motinova/codec.h"
#include "motinova/frame.h"

namespace fleetgw::storage {
class Store;
}

namespace fleetgw::command {

using motinova::Micros;

class DiagCapture {
 public:
  struct Record {
    motinova::AppFrame frame;
    std::int64_t heard_wall_us = 0;
  };

  explicit DiagCapture(storage::Store& store, Micros persist_interval = Micros{60'000'000});

  void on_message(const motinova::DecodedMessage& msg, std::int64_t wall_us);
  void tick(Micros now);
  // The earliest bus time at which tick() writes a changed record; nullopt: nothing to write.
  std::optional<Micros> next_due() const;
  // The last record of this catalogue message ("mc_lifetime_1", "mc_lifetime_2",
  // "pack_stats"), or nullptr.
  const Record* latest(std::string_view message) const;
  // The message names captured so far, for listings.
  std::vector<std::string> captured() const;

 private:
  struct Slot {
    std::optional<Record> record;
    bool dirty = false;
    std::optional<Micros> written;
  };
  void persist(const std::string& name, Slot& slot, Micros now);

  storage::Store& store_;
  Micros persist_interval_;
  std::map<std::string, Slot, std::less<>> slots_;
};

}  // namespace fleetgw::command
