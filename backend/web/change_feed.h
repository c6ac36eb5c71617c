// What changed in the database, for the live updates (server-sent events) of every console
// connected to this instance.
//
// Why polling and not LISTEN/NOTIFY: the ingest (which owns its tables and writes them) sends no
// NOTIFY, and this program must not add triggers to tables it does not own. So one thread per
// instance asks PostgreSQL, every `interval`, for a few maxima (latest vehicle_state and status
// arrival, latest alarm committed, latest acknowledgement): one small query per interval
// whatever the number of consoles, and a console learns of a change within about one interval.
//
// Contract:
//  * Cursor counts changes: `fleet` grows when any vehicle's state, status or alarms changed,
//    `alarms` when an alarm arrived, was acknowledged or resolved, `commands` when a console
//    command was recorded or its result stored (by any instance).
//  * wait_change() blocks until the cursor differs from `seen`, `timeout` passes or stop() is
//    called, and returns the current cursor. Thread-safe.
//  * A failing query (database down, ingest schema not there yet) is logged once per kind of
//    failure and retried at the next interval. The destructor stops and joins the thread.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

namespace fleetgw::web {

class ChangeFeed {
 public:
  struct Cursor {
    std::uint64_t fleet = 0;
    std::uint64_t alarms = 0;
    std::uint64_t commands = 0;  // a console command was sent or its result arrived
    bool operator==(const Cursor&) const = default;
  };

  ChangeFeed(std::string conninfo, std::chrono::milliseconds interval);
  ~ChangeFeed();
  ChangeFeed(const ChangeFeed&) = delete;
  ChangeFeed& operator=(const ChangeFeed&) = delete;

  Cursor wait_change(Cursor seen, std::chrono::milliseconds timeout);
  Cursor current();
  // A command result stored by this instance: announced at once, not at the next poll (the
  // click-to-result time is what an operator feels). Other instances see it by polling.
  void notify_commands();
  void stop();
  bool stopped();

 private:
  void run(const std::stop_token& stop);

  std::string conninfo_;
  std::chrono::milliseconds interval_;
  std::mutex mu_;
  std::condition_variable_any cv_;
  Cursor cursor_;
  bool stopped_ = false;
  std::jthread thread_;  // last: started once every member above exists
};

}  // namespace fleetgw::web
