#include "gateway/node/node_config.h"

#include <set>
#include <stdexcept>
#include <string>

#ifndef FLEETGW_VERSION
#define FLEETGW_VERSION "0.0.0"
#endif
#ifndef FLEETGW_NODE_BUILD_DATE
#define FLEETGW_NODE_BUILD_DATE "19700101"
#endif

namespace fleetgw::node {
namespace {

std::string hex(unsigned value, int digits) {
  static constexpr char kDigits[] = "0123456789ABCDEF";
  std::string out = "0x";
  for (int i = digits - 1; i >= 0; --i) out += kDigits[(value >> (4 * i)) & 0xF];
  return out;
}

[[noreturn]] void fail(const std::string& what) {
  throw std::invalid_argument("node config: " + what);
}

}  // namespace

std::string Identity::firmware() const {
  return format_firmware(firmware_version.empty() ? FLEETGW_VERSION : firmware_version,
                         firmware_date.empty() ? FLEETGW_NODE_BUILD_DATE : firmware_date);
}

std::vector<PollEntry> default_poll_table(const std::array<bool, motinova::kLockCount>& fitted) {
  using namespace ids;
  auto cmd = [](uint8_t function) { return static_cast<uint16_t>(function << 8); };
  std::vector<PollEntry> t;
  // Model info and nameplate: once, and again after the node comes back (battery swap).
  t.push_back(
      {"obc_model", kIotToObc, cmd(fn::kObcReadModel), {{kObcBroadcast, fn::kObcModelInfo}}, 0s});
  // §3.3.9 (U16): 0x5100 answers either the cells or the model block. Both readings are polled;
  // the one the BMS does not honour backs off after its first timeout.
  t.push_back({"bms_model", kIotToBms, cmd(0x51), {{kBmsBroadcast, fn::kBmsModelInfo}}, 0s});
  t.push_back({"bms_nameplate", kIotToBms, cmd(0x53), {{kBmsBroadcast, fn::kBmsNameplate}}, 0s});
  // Broadcast blocks with a read command: requested only when not seen for ~1 s (§3.7, U12).
  t.push_back({"bms_status", kIotToBms, cmd(0x50), {{kBmsBroadcast, fn::kBmsStatus}}, 1s});
  t.push_back({"bms_cells", kIotToBms, cmd(0x51), {{kBmsBroadcast, fn::kBmsCells}}, 1s});
  // Fault words come every 1 s when OK; 1.5 s leaves room for jitter and still refreshes the
  // word before the 2 s "unknown" threshold.
  t.push_back({"bms_faults", kIotToBms, cmd(0x52), {{kBmsBroadcast, fn::kBmsFaults}}, 1500ms});
  // Pack lifetime statistics: 0x5400 answers 0x725/0x5028 or 0x720/0x1810 (U16).
  t.push_back({"bms_pack_stats",
               kIotToBms,
               cmd(0x54),
               {{kBmsToCdl, fn::kBmsPackStats}, {kBmsBroadcast, fn::kBmsExtra}},
               60s});
  t.push_back(
      {"mc_odometer", kIotToMc, cmd(fn::kMcReadOdometer), {{kMcBroadcast, fn::kMcOdometer}}, 10s});
  // U14: the MC answers on 0x713 like for the OBC; 0x710 and 0x716 are accepted too.
  t.push_back(
      {"mc_settings",
       kIotToMc,
       cmd(fn::kMcReadSettings),
       {{kMcToObc, fn::kMcSettings}, {kMcBroadcast, fn::kMcSettings}, {kMcToIot, fn::kMcSettings}},
       60s});
  for (int k = 0; k < motinova::kLockCount; ++k) {
    if (!fitted[static_cast<std::size_t>(k)]) continue;
    const uint8_t f = lock_function_base(k);
    const std::string prefix = "lock" + std::to_string(k + 1);
    t.push_back({prefix + "_model",
                 lock_command_id(k),
                 cmd(f),
                 {{lock_broadcast_id(k), fn::kLockModelInfo}},
                 0s});
    t.push_back({prefix + "_status",
                 lock_command_id(k),
                 cmd(static_cast<uint8_t>(f + 1)),
                 {{lock_broadcast_id(k), fn::kLockStatus}},
                 1s});
  }
  return t;
}

std::vector<PollEntry> NodeConfig::effective_poll_table() const {
  return poll_table ? *poll_table : default_poll_table(fitted_locks);
}

void NodeConfig::validate() const {
  if (offline_timeout <= 0s) fail("offline_timeout must be positive");
  if (fault_stale_timeout <= 0s) fail("fault_stale_timeout must be positive");
  if (requests.retry_interval <= 0s) fail("requests.retry_interval must be positive");
  if (requests.timeout < requests.retry_interval) {
    fail("requests.timeout must be at least requests.retry_interval");
  }
  if (requests.failure_backoff <= 0s || requests.max_failure_backoff < requests.failure_backoff) {
    fail("requests.failure_backoff must be positive and <= max_failure_backoff");
  }
  if (requests.startup_grace < 0s) fail("requests.startup_grace must not be negative");
  if (broadcasts.model_info_period <= 0s) fail("broadcasts.model_info_period must be positive");
  if (broadcasts.fault_period_faulty <= 0s || broadcasts.fault_period_ok <= 0s) {
    fail("broadcasts fault periods must be positive");
  }
  if (broadcasts.event_transmissions < 1 || broadcasts.event_transmissions > 10) {
    fail("broadcasts.event_transmissions must be within 1..10");
  }
  if (broadcasts.event_interval <= 0s) fail("broadcasts.event_interval must be positive");
  if (shutdown.ready_timeout <= 0s) fail("shutdown.ready_timeout must be positive");
  if (locks.timeout <= 0s || locks.status_interval <= 0s || locks.command_repeat_interval <= 0s) {
    fail("locks timeouts and intervals must be positive");
  }
  (void)identity.firmware();  // throws if the FW string does not fit
  (void)model_info_frame(identity.model, identity.serial, identity.hardware, identity.firmware());

  std::set<std::string> names;
  for (const PollEntry& e : effective_poll_table()) {
    const std::string where = "poll entry '" + e.name + "': ";
    if (e.name.empty()) fail("poll entry without a name");
    if (!names.insert(e.name).second) fail(where + "duplicate name");
    if (!motinova::is_motinova_id(e.target_id) ||
        motinova::source_of(e.target_id) != motinova::Node::kIot ||
        motinova::target_of(e.target_id) == motinova::Node::kBroadcast) {
      fail(where + "target " + hex(e.target_id, 3) + " is not an IOT -> node ID (0x761..0x76F)");
    }
    if ((e.command & 0xFF) != 0) {
      fail(where + "command " + hex(e.command, 4) + " carries data; reads have none (xx00)");
    }
    if (e.answers.empty()) fail(where + "no expected answer");
    for (const MessageKey& a : e.answers) {
      if (!motinova::is_motinova_id(a.can_id)) {
        fail(where + "answer ID " + hex(a.can_id, 3) + " is not a MOTINOVA ID");
      }
    }
    if (e.period < 0s) fail(where + "negative period");
  }
}

}  // namespace fleetgw::node
