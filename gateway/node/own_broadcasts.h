// The IoT node's own broadcasts on 0x760 (spec §3.5.1, Appendix A item 2): model info, the
// gateway's fault word, and the events READY / SHUTDOWN / LOCK / UNLOCK.
//
// Contract:
//  * Model info 0x1340 is sent at start() and then every `model_info_period`.
//  * Fault word 0x1504 (bits U18: 0x0001 LTE/uplink, 0x0002 BLE, 0x0004 GPS) is sent at start(),
//    immediately whenever the word changes, then every `fault_period_faulty` (200 ms) while any
//    bit is set and every `fault_period_ok` (1 s) while it is zero (§3.7, U12).
//  * Events are sent immediately and repeated every `event_interval` until
//    `event_transmissions` copies went out (U12: events carry no sequence number and may be
//    lost; every receiver treats a repeat as the same event). Starting LOCK cancels pending
//    UNLOCK repeats and vice versa, so a late repeat can never undo a newer command. Starting an
//    event that is already repeating restarts its count. stop_event() ends the repeats early
//    (e.g. SHUTDOWN once every READY arrived).
//  * The periodic broadcasts begin with start(); events go out whenever they are asked for (a
//    READY must not wait for start-up). Send failures are counted, never retried outside the
//    schedule above.
//  * Holds non-owning references to the sender and the decode options (fault-word layout).
#pragma once

#include <array>
#include <cstdint>

#include "gateway/node/frame_sender.h"
#include "gateway/node/node_config.h"
#include "motinova/frame.h"
#include "motinova/options.h"

namespace fleetgw::node {

enum class Event : uint8_t { kReady, kShutdown, kLock, kUnlock };
inline constexpr std::size_t kEventKinds = 4;
std::string_view event_name(Event e);  // "ready", "shutdown", "lock", "unlock"

struct BroadcastStats {
  uint64_t model_info = 0;
  uint64_t fault_words = 0;
  std::array<uint64_t, kEventKinds> events{};
  uint64_t send_failures = 0;
};

class OwnBroadcaster {
 public:
  // Builds the model-info frame once; throws std::invalid_argument if the identity does not fit.
  OwnBroadcaster(const Identity& identity, BroadcastPolicy policy,
                 const motinova::DecodeOptions& options, FrameSender& sender);

  void start(Micros now);
  void tick(Micros now);
  // The next periodic broadcast or event repeat (Micros::max(): none).
  Micros next_event() const;

  // Own fault bits. set_faults replaces the word; set_fault sets/clears bits. A change is sent
  // immediately (once started).
  void set_faults(uint32_t word, Micros now);
  void set_fault(uint32_t mask, bool active, Micros now);
  uint32_t faults() const { return faults_; }

  void send_event(Event e, Micros now);
  void stop_event(Event e);
  bool event_pending(Event e) const { return events_[index(e)].remaining > 0; }

  const BroadcastStats& stats() const { return stats_; }

 private:
  struct EventSchedule {
    int remaining = 0;  // transmissions still to come
    Micros next{0};
  };
  static std::size_t index(Event e) { return static_cast<std::size_t>(e); }
  static motinova::AppFrame event_frame(Event e);
  void send_faults(Micros now);
  void transmit(const motinova::AppFrame& f);

  BroadcastPolicy policy_;
  const motinova::DecodeOptions& options_;
  FrameSender& sender_;
  motinova::AppFrame model_info_;
  bool started_ = false;
  Micros next_model_info_{0};
  uint32_t faults_ = 0;
  Micros next_faults_{0};
  std::array<EventSchedule, kEventKinds> events_{};
  BroadcastStats stats_;
};

}  // namespace fleetgw::node
