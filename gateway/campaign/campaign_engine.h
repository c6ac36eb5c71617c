// The campaign engine: runs the accepted campaigns on the decoded messages of the bus, on the
// bus timeline, offline (it needs no network and no wall clock of its own), and turns what they
// collect into serialized fleetgw.v1.CampaignSamples records for the outbox.
//
// Contract:
//  * Time is the caller's `now` (the bus timeline: virtual in simulation and replay). A campaign
//    runs from start to end (start <= now < end) and only once its firmware rules hold
//    (target.firmware: the node's fw from its device_info message on the bus; until the node
//    reported it the campaign waits, a mismatch stops it: "not_targeted").
//  * Trigger rules (docs/campaigns.md "Triggers"): always; a daily UTC window [day_start_s,
//    day_end_s) (crossing midnight when start > end); inside a zone (on_zone()); a condition on one
//    signal, evaluated on every value of it before the samples of the same message: above holds
//    from value > threshold until value < threshold - hysteresis, below symmetrically; rising_edge
//    is an event when the previous value was <= threshold and this one > threshold, falling_edge
//    when it was >= threshold and is < threshold, fault_active when a fault bit goes 0 -> 1. The
//    first value seen is never an event (there is no previous one); invalid values are ignored.
//  * Sampling: every signal at most once per period (the value of the first message at least a
//    period after its previous sample). every: while the trigger holds; on_change: while it
//    holds and the value differs from the last one sampled; window: each event emits the ring's
//    samples of [event - before, event] and samples live until event + after (a later event
//    extends it); outside windows samples go to the ring (before/period + 1 per signal, oldest
//    overwritten).
//  * Records: a campaign's samples are cut into a record at 1024 samples, 30 s of bus time after
//    its first sample, at the end of a window (trigger_at_us set), and when the campaign ends
//    or is removed. Each record counts against the campaign's disk budget until release() says
//    it left the store; a sample that would not fit is dropped and counted (the next record's
//    `dropped`).
//  * CPU: messages with no campaign signal cost one hash look-up; others O(the campaigns'
//    signals in them). No allocation per message except the samples kept.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "gateway/campaign/campaign_spec.h"
#include "motinova/codec.h"

namespace fleetgw::campaign {

struct CampaignRecord {
  std::string campaign_id;
  std::uint64_t version = 0;
  int priority = 0;
  std::string payload;  // serialized fleetgw.v1.CampaignSamples
  std::size_t samples = 0;
};

enum class RunState : std::uint8_t { kScheduled, kWaitingFirmware, kNotTargeted, kRunning, kEnded };
std::string_view run_state_name(RunState state);  // "scheduled", "waiting_firmware", ...

struct CampaignCounters {
  std::uint64_t samples = 0;  // kept (in records or pending)
  std::uint64_t dropped = 0;  // refused by the disk budget
  std::uint64_t records = 0;
  std::uint64_t record_bytes = 0;
  std::uint64_t bytes_in_store = 0;  // recorded and not yet released
  std::uint64_t events = 0;          // trigger events (condition)
};

class CampaignRunner;

class CampaignEngine {
 public:
  CampaignEngine();
  ~CampaignEngine();
  CampaignEngine(const CampaignEngine&) = delete;
  CampaignEngine& operator=(const CampaignEngine&) = delete;

  // Adds or replaces (same id) a campaign; a replaced one's pending samples are recorded first.
  void put(CompiledCampaign campaign, Micros now);
  void remove(std::string_view id, Micros now);
  std::size_t size() const { return runners_.size(); }

  void on_message(Micros now, const motinova::DecodedMessage& message);
  // The geofence's confirmed state (issue 29, zone triggers): the bike entered (`inside`) or
  // left the zone of this id and name. A zone campaign holds while the bike is inside the zone
  // it names (by id or name); a campaign added later starts from the zones the bike is in.
  void on_zone(std::string_view zone_id, std::string_view zone_name, bool inside);
  // Cuts records that are due by age or window end, ends campaigns past their end.
  void tick(Micros now);
  // Records cut since the last call.
  std::vector<CampaignRecord> take_records();
  // `bytes` of `id`'s records left the store (acknowledged or evicted).
  void release(std::string_view id, std::uint64_t bytes);
  // What the store holds of all campaigns' records (the outbox depth of their priorities): each
  // campaign's share is scaled down to it (records drain in sequence order across campaigns,
  // so the split is an estimate; 0 is exact).
  void store_holds(std::uint64_t bytes);
  // The same for the campaigns of one priority (0..9): the store queues them at an outbox
  // priority of their own, so its depth there (acks and evictions) is theirs alone.
  void store_holds_at(int priority, std::uint64_t bytes);
  // `id`'s records in the store, counted from the store at start-up (the outbox survives a
  // restart, so does the campaign's use of its disk budget).
  void set_bytes_in_store(std::string_view id, std::uint64_t bytes);

  struct View {
    const CompiledCampaign* campaign;
    RunState state;
    CampaignCounters counters;
  };
  std::vector<View> view(Micros now) const;

 private:
  void rebuild_index();
  template <typename Pred>
  void scale_to(std::uint64_t bytes, Pred pred);
  void note_firmware(const motinova::DecodedMessage& message);

  std::vector<std::unique_ptr<CampaignRunner>> runners_;
  struct Hook {
    CampaignRunner* runner;
    int slot;  // signal index in the campaign, -1: its condition
    const motinova::Signal* signal;
    std::size_t value_at = 0;  // where its field was in the message's values last time
  };
  std::unordered_map<const motinova::MessageDesc*, std::vector<Hook>> index_;
  std::map<motinova::Node, std::string> firmware_;                // fw seen on the bus per node
  std::map<std::string, std::string, std::less<>> zones_inside_;  // id -> name
  std::vector<CampaignRecord> records_;
};

}  // namespace fleetgw::campaign
