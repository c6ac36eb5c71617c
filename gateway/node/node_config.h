// Configuration of the IoT node's bus behaviour: identity, timeouts, the poll table, fitted
// locks. The lead fills it from the TOML config file; every default is the spec's best guess
// (§3.7, U12, U16) so a default-constructed NodeConfig behaves correctly on a standard bike.
//
// Contract:
//  * Plain value types. validate() throws std::invalid_argument naming the offending item
//    (e.g. "poll entry 'bms_stats': ...") for configuration errors; components call it on
//    construction so a bad config never reaches the bus.
//  * All durations are motinova::Micros (virtual or real time, the node never reads a clock).
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "gateway/node/messages.h"
#include "motinova/can.h"

namespace fleetgw::node {

using motinova::Micros;
using namespace std::chrono_literals;

// One line of the poll table: "send read `command` to `target_id`; the answer is any of
// `answers`; keep the answer no older than `period`".
//
// Answers are matched by (CAN ID, function) because they arrive on the answering node's
// broadcast ID (§1.4), so a cyclic broadcast of the same block counts as fresh data too: a block
// that is broadcast on its own is never polled (the "stale → request" rule of §3.7).
struct PollEntry {
  std::string name;                 // for logs and the poll-result callback: "bms_pack_stats"
  uint16_t target_id = 0;           // 0x761 (MC), 0x762 (BMS), 0x763 (OBC), 0x767..0x76B (locks)
  uint16_t command = 0;             // read COMMAND, function << 8 | 0 (reads carry no data)
  std::vector<MessageKey> answers;  // any of these counts as the answer
  // 0: read once at start-up and again whenever the target node comes back online (model info,
  // nameplate). >0: read when the newest answer is older than this.
  Micros period{0};
};

struct Identity {
  std::string model = "FLEETGW";
  std::string serial;  // bike / gateway serial number
  std::string hardware = "HW1.0";
  std::string firmware_version;  // "0.1.0"; empty: the build's version (FLEETGW_VERSION)
  std::string firmware_date;     // YYYYMMDD; empty: the build date (SOURCE_DATE_EPOCH honoured)

  // The FW field of the model-info block, "Vx.x.x_YYYYMMDD". Throws std::invalid_argument if it
  // does not fit.
  std::string firmware() const;
};

struct RequestPolicy {
  Micros retry_interval = 200ms;  // §3.7: repeat a request every 200 ms ...
  Micros timeout = 1s;            // ... and give up after 1 s
  // After a timed-out poll the entry waits failure_backoff, doubling per consecutive failure up
  // to max_failure_backoff, so an absent node does not cost 5 frames every second forever.
  Micros failure_backoff = 5s;
  Micros max_failure_backoff = 60s;
  // Periodic entries wait this long after start-up before polling, so blocks that are broadcast
  // on their own get the chance to arrive first (no needless reads at boot).
  Micros startup_grace = 1s;
};

struct BroadcastPolicy {
  Micros model_info_period = 10s;      // 0x760/0x1340, also sent at start-up
  Micros fault_period_faulty = 200ms;  // 0x760/0x1504 while a fault bit is set (U12) ...
  Micros fault_period_ok = 1s;         // ... and while there is none
  // Events (READY, SHUTDOWN, LOCK, UNLOCK) carry no sequence number and may be lost; §3.7 and
  // U12 suggest sending them 2-3 times. Each is sent at once and then repeated up to this total.
  int event_transmissions = 3;
  Micros event_interval = 200ms;
};

struct ShutdownPolicy {
  Micros ready_timeout = 1s;   // §3.8.2: wait for READY from MC and OBC, or about 1 s
  bool order_obc_off = false;  // also send 0x763/0x7008 SHUTDOWN to the OBC
};

struct LockPolicy {
  Micros timeout = 3s;             // default actuation timeout
  Micros status_interval = 200ms;  // status read cadence while actuating
  // The command is repeated at this interval (up to event_transmissions in total) until the lock
  // reports any reaction (in-progress, target or failure state).
  Micros command_repeat_interval = 600ms;
};

struct NodeConfig {
  Identity identity;
  Micros offline_timeout = 3s;      // a node not heard for this long is offline
  Micros fault_stale_timeout = 2s;  // §3.7: a fault word not heard for 2 s is UNKNOWN
  std::array<bool, motinova::kLockCount> fitted_locks{};  // LOCK 1..5 (nodes 7..B)
  // nullopt: default_poll_table(fitted_locks).
  std::optional<std::vector<PollEntry>> poll_table;
  RequestPolicy requests;
  BroadcastPolicy broadcasts;
  ShutdownPolicy shutdown;
  LockPolicy locks;

  std::vector<PollEntry> effective_poll_table() const;
  // Throws std::invalid_argument naming the problem.
  void validate() const;
};

// The default poll table (see docs/iot-node.md for the reasoning behind each line):
//   obc_model       0x763 0x7000 -> 0x730/0x11                         once
//   bms_model       0x762 0x5100 -> 0x720/0x15                         once   (U16: or cells)
//   bms_nameplate   0x762 0x5300 -> 0x720/0x14                         once
//   bms_status      0x762 0x5000 -> 0x720/0x10                         1 s (stale rule)
//   bms_cells       0x762 0x5100 -> 0x720/0x11                         1 s (stale rule)
//   bms_faults      0x762 0x5200 -> 0x720/0x12                         1.5 s (stale rule)
//   bms_pack_stats  0x762 0x5400 -> 0x725/0x50 or 0x720/0x18           60 s
//   mc_odometer     0x761 0x3500 -> 0x710/0x15                         10 s
//   mc_settings     0x761 0x3300 -> 0x713/0x54 (or 0x710, 0x716: U14)  60 s
//   lockN_model     0x767+k F<<8 -> 0x7n0/0x12                         once  (fitted locks)
//   lockN_status    0x767+k (F+1)<<8 -> 0x7n0/0x10                     1 s   (fitted locks)
std::vector<PollEntry> default_poll_table(const std::array<bool, motinova::kLockCount>& fitted);

}  // namespace fleetgw::node
