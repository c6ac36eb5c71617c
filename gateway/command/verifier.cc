#include "gateway/command/verifier.h"

#include "gateway/command/signing.h"

#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/wire_format_lite.h>

#include <ctime>
#include <optional>
#include <stdexcept>
#include <vector>

#include "fleetgw/v1/command.pb.h"
#include "gateway/command/diag_blocks.h"
#include "gateway/command/sha256.h"
#include "gateway/common/untrusted_text.h"

namespace fleetgw::command {
namespace {

// The mc_action fields present in serialized Command bytes, in wire order, repeats included:
// protobuf keeps only the last member of a oneof, so a Command carrying two actions would run
// the last one. nullopt when the bytes cannot be walked (they parsed already; defensive).
std::optional<std::vector<int>> mc_action_fields(std::string_view bytes) {
  namespace pbio = google::protobuf::io;
  using google::protobuf::internal::WireFormatLite;
  pbio::CodedInputStream in(reinterpret_cast<const std::uint8_t*>(bytes.data()),
                            static_cast<int>(bytes.size()));
  std::vector<int> fields;
  for (;;) {
    const std::uint32_t tag = in.ReadTag();
    if (tag == 0) break;
    const int number = WireFormatLite::GetTagFieldNumber(tag);
    if (number >= v1::Command::kSpeedLimitFieldNumber &&
        number <= v1::Command::kPowerOffFieldNumber) {
      // A handful at most are reported: the count is what matters.
      if (fields.size() < 8) fields.push_back(number);
    }
    if (!WireFormatLite::SkipField(&in, tag)) return std::nullopt;
  }
  return fields;
}

std::string_view mc_field_name(int number) {
  switch (number) {
    case v1::Command::kSpeedLimitFieldNumber:
      return "speed_limit";
    case v1::Command::kAssistLevelFieldNumber:
      return "assist_level";
    case v1::Command::kHeadlightFieldNumber:
      return "headlight";
    case v1::Command::kClearTripFieldNumber:
      return "clear_trip";
    default:
      return "power_off";
  }
}

Rejection reject(RejectReason reason, std::string detail, std::string command_id = {},
                 bool authenticated = false, std::string command_sha256 = {}) {
  return Rejection{reason,        std::move(detail),         std::move(command_id),
                   authenticated, std::move(command_sha256), {}};
}

// A payload that failed authentication: bound to the whole payload, never to its command bytes.
Rejection unauthentic(std::span<const std::uint8_t> payload, RejectReason reason,
                      std::string detail, std::string command_id = {}) {
  Rejection r{reason, std::move(detail), std::move(command_id), false, {}, {}};
  r.payload_sha256 = sha256({reinterpret_cast<const char*>(payload.data()), payload.size()});
  return r;
}

// Longest excerpt of a received string quoted in a rejection detail.
constexpr std::size_t kMaxQuoted = 64;

std::string quote_untrusted(std::string_view untrusted) {
  return "'" + common::untrusted_excerpt(untrusted, kMaxQuoted) + "'";
}

// Vehicle ids follow the same rule as the ids the operator tool accepts (signing.h).
bool valid_vehicle_id(std::string_view id) {
  return is_valid_tool_id(id);
}

}  // namespace

std::string_view reject_reason_name(RejectReason reason) {
  switch (reason) {
    case RejectReason::kMalformed:
      return "malformed";
    case RejectReason::kUnknownKey:
      return "unknown_key";
    case RejectReason::kBadSignature:
      return "signature_invalid";
    case RejectReason::kWrongVehicle:
      return "wrong_vehicle";
    case RejectReason::kClockUnsynchronised:
      return "clock_unsynchronised";
    case RejectReason::kExpired:
      return "expired";
    case RejectReason::kIssuedInFuture:
      return "issued_in_future";
    case RejectReason::kValidityTooLong:
      return "validity_too_long";
    case RejectReason::kReplayed:
      return "replayed";
    case RejectReason::kLockNotFitted:
      return "lock_not_fitted";
    case RejectReason::kLockOffline:
      return "lock_offline";
    case RejectReason::kInterlockMoving:
      return "interlock_moving";
    case RejectReason::kInterlockMotionUnknown:
      return "interlock_motion_unknown";
    case RejectReason::kLockBusy:
      return "lock_busy";
    case RejectReason::kShuttingDown:
      return "shutting_down";
    case RejectReason::kStorageError:
      return "storage_error";
    case RejectReason::kMcOffline:
      return "mc_offline";
    case RejectReason::kMcBusy:
      return "mc_busy";
    case RejectReason::kMcStateUnknown:
      return "mc_state_unknown";
    case RejectReason::kOutOfRange:
      return "out_of_range";
    case RejectReason::kUnknownAssistLevel:
      return "unknown_assist_level";
    case RejectReason::kLockMoving:
      return "lock_moving";
    case RejectReason::kNoParkingZone:
      return "no_parking_zone";
    case RejectReason::kNoStartZone:
      return "no_start_zone";
    case RejectReason::kDelegationInvalid:
      return "delegation_invalid";
    case RejectReason::kRevoked:
      return "revoked";
    case RejectReason::kOutOfScope:
      return "out_of_scope";
    case RejectReason::kDelegationNotYetValid:
      return "delegation_not_yet_valid";
    case RejectReason::kDelegationExpired:
      return "delegation_expired";
    case RejectReason::kDiagBusy:
      return "diag_busy";
  }
  return "unknown";
}

std::string_view mc_action_name(McActionKind kind) {
  switch (kind) {
    case McActionKind::kNone:
      return "lock";
    case McActionKind::kSpeedLimit:
      return "speed_limit";
    case McActionKind::kAssistLevel:
      return "assist_level";
    case McActionKind::kHeadlight:
      return "headlight";
    case McActionKind::kClearTrip:
      return "clear_trip";
    case McActionKind::kPowerOff:
      return "power_off";
  }
  return "unknown";
}

bool is_valid_command_id(std::string_view id) {
  if (id.empty() || id.size() > 128) return false;
  for (const char c : id) {
    if (c <= ' ' || c > '~') return false;
  }
  return true;
}

std::string format_utc(Micros t) {
  const std::int64_t us = t.count();
  std::int64_t secs = us / 1'000'000;
  std::int64_t frac = us % 1'000'000;
  if (frac < 0) {
    frac += 1'000'000;
    --secs;
  }
  const std::time_t tt = static_cast<std::time_t>(secs);
  std::tm tm{};
  if (gmtime_r(&tt, &tm) == nullptr) return std::to_string(us) + "us";
  char buf[40];
  const std::size_t n = std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
  char out[64];
  std::snprintf(out, sizeof out, "%.*s.%06lldZ", static_cast<int>(n), buf,
                static_cast<long long>(frac));
  return out;
}

CommandVerifier::CommandVerifier(VerifierConfig config)
    : config_(std::move(config)),
      roots_(config_.root_keys),
      identity_{config_.vehicle_id, config_.groups} {
  if (!valid_vehicle_id(config_.vehicle_id)) {
    throw std::invalid_argument("command: invalid vehicle id '" + config_.vehicle_id + "'");
  }
  for (const auto& g : config_.groups) {
    if (!valid_vehicle_id(g)) {
      throw std::invalid_argument("vehicle.groups: '" + g +
                                  "' is not 1..64 characters of [A-Za-z0-9._-]");
    }
  }
  for (const auto& [id, text] : config_.trusted_keys) {
    if (id.empty()) throw std::invalid_argument("command.trusted_keys: empty key id");
    auto key = Ed25519PublicKey::from_base64(text);
    if (!key) {
      throw std::invalid_argument("command.trusted_keys." + id +
                                  ": not a base64 raw Ed25519 public key (32 bytes)");
    }
    keys_.emplace(id, std::move(*key));
  }
}

VerifyResult CommandVerifier::authenticate(std::span<const std::uint8_t> payload) const {
  if (payload.size() > config_.max_payload_bytes) {
    return reject(RejectReason::kMalformed, "payload of " + std::to_string(payload.size()) +
                                                " bytes exceeds " +
                                                std::to_string(config_.max_payload_bytes));
  }
  v1::SignedCommand signed_cmd;
  if (!signed_cmd.ParseFromArray(payload.data(), static_cast<int>(payload.size()))) {
    return unauthentic(payload, RejectReason::kMalformed, "not a fleetgw.v1.SignedCommand");
  }
  if (signed_cmd.command().empty()) {
    return unauthentic(payload, RejectReason::kMalformed, "empty command");
  }
  v1::Command cmd;
  if (!cmd.ParseFromString(signed_cmd.command())) {
    return unauthentic(payload, RejectReason::kMalformed,
                       "command bytes are not a fleetgw.v1.Command");
  }
  // The id is reported back even for commands that fail later checks, but only when it is
  // well-formed: arbitrary bytes never reach logs, topics or the database.
  std::string id = is_valid_command_id(cmd.command_id()) ? cmd.command_id() : std::string();
  auto bad = [&](std::string detail) {
    return unauthentic(payload, RejectReason::kMalformed, std::move(detail), id);
  };
  if (signed_cmd.signature().empty()) return bad("no signature");
  if (signed_cmd.key_id().empty()) return bad("no key id");
  if (cmd.command_id().empty()) return bad("no command_id");
  if (id.empty()) return bad("command_id is not 1..128 printable ASCII characters");
  if (cmd.vehicle_id().empty()) return bad("no vehicle_id");
  if (cmd.issued_at_us() <= 0) return bad("no issued_at_us");
  if (cmd.expires_at_us() <= 0) return bad("no expires_at_us");
  if (cmd.expires_at_us() <= cmd.issued_at_us()) return bad("expires_at_us <= issued_at_us");
  McRequest mc;
  DiagRequest diag;
  if (cmd.has_diagnostic_read()) {
    // Issue 29: a read is never mixed with an actuation (an older gateway would run that part).
    if (cmd.action() != v1::COMMAND_ACTION_UNSPECIFIED ||
        cmd.target_case() != v1::Command::TARGET_NOT_SET ||
        cmd.mc_action_case() != v1::Command::MC_ACTION_NOT_SET) {
      return bad("a diagnostic read must not carry a lock or MC action");
    }
    if (auto problem = parse_diag_read(cmd.diagnostic_read(), diag)) return bad(*problem);
  } else if (cmd.mc_action_case() != v1::Command::MC_ACTION_NOT_SET) {
    // One action per command: the parse kept only the last of several.
    const auto fields = mc_action_fields(signed_cmd.command());
    if (!fields) return bad("command bytes cannot be walked");
    if (fields->size() > 1) {
      std::string names;
      for (const int f : *fields)
        names += (names.empty() ? "" : ", ") + std::string(mc_field_name(f));
      return bad("carries more than one MC action (" + names + "); one per command");
    }
    // Never both: a gateway that predates mc_action would execute the lock part alone.
    if (cmd.action() != v1::COMMAND_ACTION_UNSPECIFIED) {
      return bad("an MC action must not carry a lock action");
    }
    if (cmd.target_case() != v1::Command::TARGET_NOT_SET) {
      return bad("an MC action must not carry a lock target");
    }
    switch (cmd.mc_action_case()) {
      case v1::Command::kSpeedLimit:
        mc.kind = McActionKind::kSpeedLimit;
        // The MC carries limits in one byte (0x5408); the MC's own range is checked later.
        if (cmd.speed_limit().kmh() > 255) return bad("speed_limit.kmh above 255");
        // Absent and 0 are the same bytes in proto3; neither is a limit (assist off is the
        // assist_level action).
        if (cmd.speed_limit().kmh() == 0)
          return bad("speed_limit without kmh (1..255; 0 is not a limit)");
        mc.speed_limit_kmh = cmd.speed_limit().kmh();
        break;
      case v1::Command::kAssistLevel:
        mc.kind = McActionKind::kAssistLevel;
        if (cmd.assist_level().level().empty()) return bad("empty assist_level.level");
        mc.assist_level = cmd.assist_level().level();
        break;
      case v1::Command::kHeadlight:
        mc.kind = McActionKind::kHeadlight;
        mc.headlight_on = cmd.headlight().on();
        break;
      case v1::Command::kClearTrip:
        mc.kind = McActionKind::kClearTrip;
        break;
      case v1::Command::kPowerOff:
        mc.kind = McActionKind::kPowerOff;
        break;
      default:
        return bad("unknown mc_action");
    }
  } else {
    if (cmd.action() != v1::COMMAND_ACTION_LOCK && cmd.action() != v1::COMMAND_ACTION_UNLOCK) {
      return bad("action is neither LOCK nor UNLOCK");
    }
    switch (cmd.target_case()) {
      case v1::Command::kLockKind:
        if (cmd.lock_kind().empty()) return bad("empty lock_kind");
        break;
      case v1::Command::kWholeVehicle:
        if (!cmd.whole_vehicle()) return bad("whole_vehicle must be true when set");
        break;
      default:
        return bad("no target (lock_kind or whole_vehicle)");
    }
  }

  // A trusted key (unscoped, as before issue 28), else a key the root delegated.
  const Ed25519PublicKey* key = nullptr;
  std::optional<OpenedDelegation> delegated;
  if (const auto trusted = keys_.find(signed_cmd.key_id()); trusted != keys_.end()) {
    key = &trusted->second;
  } else if (!signed_cmd.has_delegation()) {
    return unauthentic(payload, RejectReason::kUnknownKey,
                       "key id " + quote_untrusted(signed_cmd.key_id()) + " is not trusted", id);
  } else {
    auto opened = roots_.open(signed_cmd.delegation(), signed_cmd.key_id());
    if (auto* problem = std::get_if<DelegationProblem>(&opened)) {
      return unauthentic(payload, RejectReason::kDelegationInvalid, std::move(problem->detail), id);
    }
    delegated.emplace(std::move(std::get<OpenedDelegation>(opened)));
    key = &delegated->public_key;
  }
  const auto* msg = reinterpret_cast<const std::uint8_t*>(signed_cmd.command().data());
  const auto* sig = reinterpret_cast<const std::uint8_t*>(signed_cmd.signature().data());
  if (!key->verify({msg, signed_cmd.command().size()}, {sig, signed_cmd.signature().size()})) {
    return unauthentic(payload, RejectReason::kBadSignature,
                       "Ed25519 signature does not verify with " +
                           std::string(delegated ? "delegated key " : "key ") +
                           quote_untrusted(signed_cmd.key_id()),
                       id);
  }
  // Authentic from here on: bound to the signed bytes.
  std::string digest = sha256(signed_cmd.command());
  std::string operator_id =
      cmd.operator_id().empty() ? std::string() : common::untrusted_excerpt(cmd.operator_id(), 64);
  if (cmd.vehicle_id() != config_.vehicle_id) {
    Rejection r =
        reject(RejectReason::kWrongVehicle,
               "command is for vehicle " + quote_untrusted(cmd.vehicle_id()), id, true, digest);
    r.operator_id = std::move(operator_id);
    return r;
  }

  VerifiedCommand out;
  out.command_id = std::move(id);
  out.vehicle_id = cmd.vehicle_id();
  out.key_id = signed_cmd.key_id();
  out.issued_at = Micros(cmd.issued_at_us());
  out.expires_at = Micros(cmd.expires_at_us());
  out.target = cmd.action() == v1::COMMAND_ACTION_LOCK ? node::LockTarget::kLocked
                                                       : node::LockTarget::kUnlocked;
  out.whole_vehicle = cmd.target_case() == v1::Command::kWholeVehicle;
  if (cmd.target_case() == v1::Command::kLockKind) out.lock_kind = cmd.lock_kind();
  out.mc = std::move(mc);
  out.diag = std::move(diag);
  out.command_sha256 = std::move(digest);
  out.operator_id = std::move(operator_id);
  if (delegated) out.delegation = std::move(delegated->grant);
  // What an authorize() refusal is bound to; every result of a trusted key's command is bound
  // to the command bytes, so only pay for it when it may be needed.
  if (delegated || !revocations_.lists().empty()) {
    out.payload_sha256 = sha256({reinterpret_cast<const char*>(payload.data()), payload.size()});
  }
  return out;
}

std::string_view delegation_action(const VerifiedCommand& c) {
  if (c.diag.requested()) return "diagnostics";
  if (c.mc.kind != McActionKind::kNone) return mc_action_name(c.mc.kind);
  return c.target == node::LockTarget::kLocked ? "lock" : "unlock";
}

std::optional<Rejection> CommandVerifier::authorize(const VerifiedCommand& c, Micros now,
                                                    bool clock_synchronised) const {
  // Not authorised is answered like not authentic: bound to the payload, never journaled.
  auto refuse = [&](RejectReason r, std::string detail) {
    Rejection out{r, std::move(detail), c.command_id, false, {}, c.payload_sha256};
    out.operator_id = c.operator_id;
    return out;
  };
  if (!c.delegation) {
    // A trusted key: only a root's revocation list can withdraw it.
    if (auto why = revocations_.revoked({}, 0, c.key_id)) {
      return refuse(RejectReason::kRevoked, std::move(*why));
    }
    return std::nullopt;
  }
  auto problem =
      judge(*c.delegation, delegation_action(c), identity_, now, clock_synchronised, revocations_);
  if (!problem) return std::nullopt;
  switch (problem->reason) {
    case DelegationRefusal::kRevoked:
      return refuse(RejectReason::kRevoked, std::move(problem->detail));
    case DelegationRefusal::kOutOfScope:
      return refuse(RejectReason::kOutOfScope, std::move(problem->detail));
    case DelegationRefusal::kClockUnsynchronised:
      return refuse(RejectReason::kClockUnsynchronised, std::move(problem->detail));
    case DelegationRefusal::kNotYetValid:
      return refuse(RejectReason::kDelegationNotYetValid, std::move(problem->detail));
    case DelegationRefusal::kExpired:
      return refuse(RejectReason::kDelegationExpired, std::move(problem->detail));
    case DelegationRefusal::kInvalid:
      break;
  }
  return refuse(RejectReason::kDelegationInvalid, std::move(problem->detail));
}

RevocationVerdict CommandVerifier::offer_revocations(std::span<const std::uint8_t> payload) {
  return revocations_.offer(payload, roots_);
}

std::vector<std::string> CommandVerifier::restore_revocations(std::string_view persisted) {
  return revocations_.restore(persisted, roots_);
}

std::optional<Rejection> CommandVerifier::check(VerifiedCommand& c, Micros now,
                                                bool clock_synchronised,
                                                const SeenPredicate& seen) const {
  auto reject_auth = [&](RejectReason r, std::string detail) {
    Rejection out = reject(r, std::move(detail), c.command_id, true, c.command_sha256);
    out.operator_id = c.operator_id;
    return out;
  };
  if (!clock_synchronised) {
    return reject_auth(RejectReason::kClockUnsynchronised,
                       "wall clock not synchronised (now " + format_utc(now) +
                           "): command expiry cannot be judged");
  }
  if (c.expires_at <= now) {
    return reject_auth(RejectReason::kExpired,
                       "expired at " + format_utc(c.expires_at) + ", now " + format_utc(now));
  }
  if (c.issued_at > now + config_.clock_skew) {
    return reject_auth(RejectReason::kIssuedInFuture,
                       "issued at " + format_utc(c.issued_at) + ", now " + format_utc(now) +
                           " (allowed skew " +
                           std::to_string(config_.clock_skew.count() / 1'000'000) + " s)");
  }
  if (c.expires_at - c.issued_at > config_.max_validity) {
    return reject_auth(
        RejectReason::kValidityTooLong,
        "valid for " + std::to_string((c.expires_at - c.issued_at).count() / 1'000'000) +
            " s, at most " + std::to_string(config_.max_validity.count() / 1'000'000) + " s");
  }
  if (seen && seen(c.command_id, now)) {
    return reject_auth(RejectReason::kReplayed, "command id already seen");
  }
  const bool diag_lock = c.diag.block == v1::DIAGNOSTIC_BLOCK_LOCK_MODEL;
  if (diag_lock || (!c.whole_vehicle && c.mc.kind == McActionKind::kNone && !c.diag.requested())) {
    if (diag_lock) c.lock_kind = c.diag.lock_kind;
    c.lock_index = -1;
    for (std::size_t k = 0; k < config_.lock_kinds.size(); ++k) {
      if (!config_.lock_kinds[k].empty() && config_.lock_kinds[k] == c.lock_kind) {
        c.lock_index = static_cast<int>(k);
        break;
      }
    }
    if (c.lock_index < 0) {
      return reject_auth(RejectReason::kLockNotFitted,
                         "no " + quote_untrusted(c.lock_kind) + " lock fitted to this vehicle");
    }
  }
  return std::nullopt;
}

VerifyResult CommandVerifier::verify(std::span<const std::uint8_t> payload, Micros now,
                                     bool clock_synchronised, const SeenPredicate& seen) const {
  VerifyResult r = authenticate(payload);
  if (auto* c = std::get_if<VerifiedCommand>(&r)) {
    if (auto rejection = authorize(*c, now, clock_synchronised)) return std::move(*rejection);
    if (auto rejection = check(*c, now, clock_synchronised, seen)) return std::move(*rejection);
  }
  return r;
}

std::string_view command_result_name(v1::CommandResultCode code) {
  switch (code) {
    case v1::COMMAND_RESULT_CODE_SUCCEEDED:
      return "succeeded";
    case v1::COMMAND_RESULT_CODE_FAILED:
      return "failed";
    case v1::COMMAND_RESULT_CODE_TIMEOUT:
      return "timeout";
    case v1::COMMAND_RESULT_CODE_REJECTED:
      return "rejected";
    default:
      return "unspecified";
  }
}

}  // namespace fleetgw::command
