// Drives one physical lock to "locked" or "unlocked" and confirms it (spec §3.5.4, §3.8.3):
// the primitive under the remote-lock service.
//
// Contract:
//  * start() writes LOCK ((F+2)<<8|4) or UNLOCK ((F+3)<<8|6) to 0x767+k and then confirms by
//    reading the status ((F+1)<<8 → 0x7n0/0x1010) every `status_interval` and by watching the
//    lock's status broadcasts. Requests go through the RequestEngine, so they never overlap
//    with other requests to the same lock ID.
//  * Only status frames received after start() count. The job ends with
//      kSucceeded  state byte == target (1 unlocked / 2 locked),
//      kFailed     state byte == the failure of this direction (5 unlock failed / 6 lock failed),
//                  unless the lock already reported that failure before start() and has not
//                  reported anything else since (a stale failure from an earlier attempt),
//      kTimeout    neither within `timeout` (default 3 s),
//    with the last state byte seen (if any) and the elapsed time.
//  * Until the lock shows any reaction (in-progress, target or failure state), the command is
//    repeated every `command_repeat_interval`, at most `command_transmissions` times in total
//    (§3.7: events may be lost).
//  * One job per lock: a second start() on a busy lock is refused (kBusy), as is a lock that is
//    not fitted. The callback runs after the job was removed, so it may start a new one.
//  * Time advances only through `now`; tick() must run at next_event() (or at least every
//    status_interval).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <optional>

#include "gateway/node/node_config.h"
#include "gateway/node/request_engine.h"

namespace fleetgw::node {

enum class LockTarget : uint8_t { kUnlocked, kLocked };
std::string_view lock_target_name(LockTarget t);  // "unlocked", "locked"

enum class LockOutcome : uint8_t { kSucceeded, kFailed, kTimeout };
std::string_view lock_outcome_name(LockOutcome o);  // "succeeded", "failed", "timeout"

enum class LockStart : uint8_t { kStarted, kBusy, kNotFitted, kBadIndex };
std::string_view lock_start_name(LockStart s);

struct LockResult {
  int lock_index = 0;  // 0-based (LOCK 1 = 0 = node 7)
  LockTarget target = LockTarget::kLocked;
  LockOutcome outcome = LockOutcome::kTimeout;
  std::optional<uint8_t> final_state;  // last lock-state byte seen during the job
  Micros elapsed{0};
  int commands_sent = 0;
};

class LockActuator {
 public:
  using Callback = std::function<void(const LockResult&)>;

  LockActuator(std::array<bool, motinova::kLockCount> fitted, LockPolicy policy,
               RequestPolicy requests, int command_transmissions, RequestEngine& engine);
  ~LockActuator();
  LockActuator(const LockActuator&) = delete;
  LockActuator& operator=(const LockActuator&) = delete;

  // `timeout` defaults to LockPolicy::timeout.
  LockStart start(int lock_index, LockTarget target, Micros now, Callback on_done,
                  std::optional<Micros> timeout = std::nullopt);

  void on_frame(const motinova::AppFrame& frame, Micros now);
  void tick(Micros now);
  // The next deadline, command repeat or status read of a running job (Micros::max(): idle).
  Micros next_event() const;

  bool busy(int lock_index) const;
  bool any_busy() const;
  // Latest lock-state byte seen from this lock (jobs or not).
  std::optional<uint8_t> last_state(int lock_index) const;

 private:
  struct Job {
    LockTarget target = LockTarget::kLocked;
    Micros started{0};
    Micros deadline{0};
    Callback on_done;
    std::optional<uint8_t> initial_state;  // known before start()
    std::optional<uint8_t> state;          // latest seen since start()
    bool changed = false;                  // a state different from initial_state was seen
    bool reacted = false;
    int commands_sent = 0;
    Micros last_command{0};
    RequestId read_id = 0;  // 0: no read in flight
    Micros last_read{0};
  };

  void send_command(int k, Job& job, Micros now);
  void send_read(int k, Job& job, Micros now);
  void observe(int k, uint8_t state, Micros now);
  void finish(int k, LockOutcome outcome, Micros now);

  std::array<bool, motinova::kLockCount> fitted_;
  LockPolicy policy_;
  RequestPolicy requests_;
  int command_transmissions_;
  RequestEngine& engine_;
  std::array<std::optional<Job>, motinova::kLockCount> jobs_;
  std::array<std::optional<uint8_t>, motinova::kLockCount> last_state_;
  Micros last_now_{0};
};

}  // namespace fleetgw::node
