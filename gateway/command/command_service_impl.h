// Internal to the command service (not part of its API): the state behind CommandService and
// the functions of its parts, one idea per source file:
//   command_service.cc    the public wrapper, configuration, start-up recovery and purging
//   command_intake.cc     a payload's way in: authenticate once, redelivery or id reuse,
//                         freshness checks, the pre-flight checks (offline, busy, interlocks);
//                         `busy` for what the uplink's full queue could not take
//   command_execution.cc  the journal-first start and the lock-by-lock sequence on the bus
//   command_results.cc    results: built, stored with the journal (or published unstored and
//                         journaled later), rejections, re-sent answers, the rate limit
//   motion_interlock.cc   whether the bike moves (MotionInterlock)
//   command_mc.cc         MC actions (issue 13): pre-flight, journal-first start, result
//   mc_actions.cc         MC actions on the bus and their confirmation (McActionRunner)
//   diag_service.cc       diagnostic reads (issue 29): pre-flight, journal-first start, result
// Contract: single-threaded; every function runs on the caller's thread inside one of the
// CommandService entry points. Nothing here throws to the caller for a storage failure. SQLite
// is written only inside a WriteScope (the writing entry points and run()); store_result()
// outside one -- the bus side -- keeps the result in `pending` for the next scope.
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fleetgw/v1/command.pb.h"
#include "gateway/command/command_service.h"
#include "gateway/command/diag_capture.h"
#include "gateway/command/diag_reader.h"
#include "gateway/command/mc_actions.h"
#include "gateway/command/motion_interlock.h"
#include "storage/store.h"

namespace fleetgw::command {

inline constexpr std::string_view kExecuting = "executing";
// The operator's cap in km/h as decimal text in the store's meta table; absent until the first
// successful speed-limit command (command_mc.cc).
inline constexpr std::string_view kSpeedCapKey = "command.speed_cap_kmh";

// Millisecond count of a duration, never negative.
std::int64_t to_ms(Micros d);
v1::LockState proto_state(std::optional<std::uint8_t> raw);

// Writes a batch; the reason when the store refused it (a thrown error or a returned one).
std::optional<std::string> write_batch(storage::Store& store, const storage::Batch& batch);

struct CommandService::Impl : std::enable_shared_from_this<CommandService::Impl> {
  struct Step {
    int lock_index = 0;
    v1::LockActionResult result;
    int attempts = 0;
    int commands_sent = 0;
    Micros started{0};
    Micros attempt_started{0};
  };
  struct Running {
    VerifiedCommand cmd;
    Micros received{0};
    std::vector<Step> steps;
    std::size_t next = 0;  // index of the step to run next / running
    bool broadcast_sent = false;
  };
  // A result the store refused, waiting for its journal write.
  struct Unjournaled {
    v1::CommandResult result;               // as published (stored = false)
    std::optional<Micros> journal_expires;  // set: the journal gets the final state too
    Micros received{0};
    Micros at{0};
    bool published = false;  // handed to MQTT directly; else it goes through the outbox
    bool awaiting = true;    // in take_unstored()'s output, unstored_handed() not yet called
  };
  // A result concluded on the bus, waiting for its write (store_result's arguments).
  struct Pending {
    v1::CommandResult result;
    Micros at{0};
    std::optional<Micros> journal_expires;
    std::optional<Micros> received;
    std::optional<int> speed_cap;  // a confirmed speed limit: the cap, in the same transaction
  };
  // Marks an entry point that may write SQLite; the outermost one first writes what the bus
  // side concluded meanwhile, so results keep their order.
  class WriteScope {
   public:
    explicit WriteScope(Impl& impl);
    ~WriteScope() { impl_.writing = outer_; }
    WriteScope(const WriteScope&) = delete;
    WriteScope& operator=(const WriteScope&) = delete;

   private:
    Impl& impl_;
    bool outer_;
  };

  Impl(CommandServiceConfig c, CommandContext ctx);

  CommandServiceConfig config;
  CommandContext context;
  CommandVerifier verifier;
  MotionInterlock motion;
  McActionRunner mc;  // after `motion`, which it reads
  // The MC action in progress (one at a time), for its journal entry and result.
  struct McRun {
    VerifiedCommand cmd;
    Micros received{0};
  };
  std::optional<McRun> mc_run;
  // Diagnostic reads (issue 29): the bus side, the lifetime records seen, the read in progress.
  DiagReader diag;
  DiagCapture capture;
  std::optional<McRun> diag_run;
  std::vector<std::unique_ptr<Running>> running;
  CommandStats stats;
  ResultObserver observer;
  LockGuard lock_guard;    // geofence no-parking zones; empty: every lock may run
  LockGuard unlock_guard;  // geofence no-start zones (issue 27); empty: every unlock may run
  // Rate limit for results not tied to a new authenticated command (token bucket per minute).
  double tokens = 0;
  Micros tokens_at{0};
  Micros next_purge{0};
  // SHA-256 of the commands journaled (or answered) by this process, until they expire: a
  // command that reuses such an id with different bytes is not a redelivery but a different
  // command (backend bug or id reuse) and is rejected as "replayed" instead of getting the
  // other command's result. Authenticated commands only, so an attacker cannot grow it.
  std::map<std::string, std::pair<std::string, Micros>, std::less<>> known;
  static constexpr std::size_t kMaxKnown = 10'000;
  // Results the store refused, by command id (empty id: outbox-only results are not kept).
  std::map<std::string, Unjournaled, std::less<>> unjournaled;
  Micros next_journal_retry{0};
  static constexpr Micros kJournalRetryInterval = 1s;
  bool writing = false;          // inside a WriteScope
  std::vector<Pending> pending;  // concluded on the bus, not yet written (bounded, see .h)
  // Outputs (CommandService::take_stored / take_unstored).
  std::size_t stored_count = 0;
  std::vector<UnstoredResult> unstored_out;

  Micros wall(Micros now) const { return context.wall_clock ? context.wall_clock() : now; }
  void remember(const VerifiedCommand& c, Micros keep_until);
  std::string state_name(std::optional<std::uint8_t> raw) const;
  std::string_view kind_of(int k) const;
  Running* find_running(std::string_view id);
  // A lock command or an MC action with this id is in progress.
  bool executing(std::string_view id);

  // command_intake.cc
  Disposition on_payload(std::span<const std::uint8_t> payload, Micros now);
  // An id answered before (stored or unstored), running, or reused by different bytes: its
  // answer. nullopt: a new id. Needs only cmd.command_id and cmd.command_sha256.
  std::optional<Disposition> answer_known(const VerifiedCommand& cmd, Micros now);
  Disposition answer_busy(VerifiedCommand cmd, Micros now);
  Disposition answer_stopping(std::span<const std::uint8_t> payload, Micros now);
  // answer_busy() and answer_stopping(): the command is answered `rejected` with `reason`, not
  // judged beyond its signature, not journaled, not marked as seen.
  Disposition answer_not_run(VerifiedCommand cmd, Micros now, std::string reason,
                             std::string_view why_logged);
  std::optional<Rejection> preflight(const VerifiedCommand& cmd, Micros now);
  std::vector<int> lock_indices(const VerifiedCommand& cmd) const;
  std::optional<Rejection> interlock(int k, node::LockTarget target, Micros now);

  // command_execution.cc
  Disposition start(VerifiedCommand cmd, Micros now);
  // Writes the command's "executing" journal entry, which must be on disk before the first CAN
  // write (after a crash from there on, recover() answers without acting again), and counts it
  // accepted. When the store refuses, the command is answered storage_error and that rejection
  // is returned: the caller must not act.
  std::optional<Disposition> journal_executing(const VerifiedCommand& cmd, Micros now);
  void advance(Running& r, Micros now);
  bool attempt(Running& r, Step& s, Micros now);
  void on_lock_result(const std::string& id, const node::LockResult& res);
  void finish(Running& r, Micros now);

  // command_mc.cc
  Disposition on_mc_command(VerifiedCommand cmd, Micros now);
  void finish_mc(McOutcome outcome, Micros now);

  // diag_service.cc
  Disposition on_diag_command(VerifiedCommand cmd, Micros now);
  void finish_diag(DiagOutcome outcome, Micros now);
  DiagOutcome read_captured(const DiagBlockSpec& spec) const;

  // command_results.cc
  // Outside a WriteScope: kept in `pending` (written by the next scope). `speed_cap`: a
  // confirmed speed limit, stored in the same transaction.
  void store_result(v1::CommandResult r, Micros now, std::optional<Micros> journal_expires,
                    std::optional<Micros> received, std::optional<int> speed_cap = std::nullopt);
  void write_pending();
  // A result the store refused, for the runtime to publish directly.
  void emit_unstored(const v1::CommandResult& r);
  void unstored_handed(std::string_view command_id, bool handed);
  void answer_unstored(v1::CommandResult r, Micros now, std::optional<Micros> journal_expires,
                       std::optional<Micros> received);
  void retry_unjournaled(Micros now);
  void purge(Micros now);
  Disposition reject(const Rejection& rej, Micros now, std::optional<Micros> expires,
                     bool always_answer = false);
  Disposition duplicate(const storage::CommandJournalRow& entry, const std::string& sha, Micros now,
                        const std::string& operator_id = {});
  Disposition duplicate_unjournaled(const Unjournaled& u, Micros now);
  // Answers a command a previous run left "executing"; bound to `sha` (the digest of the bytes
  // just received again) or, when empty, to the digest the journal kept.
  // operator_id: the redelivered command's (the journal does not keep it).
  void finish_interrupted(const storage::CommandJournalRow& entry, Micros now,
                          const std::string& sha = {}, const std::string& operator_id = {});
  void count(const v1::CommandResult& r);
  bool take_token(Micros now);
};

}  // namespace fleetgw::command
