#include "gateway/command/delegation.h"

#include <algorithm>
#include <array>
#include <ctime>
#include <stdexcept>

#include "fleetgw/v1/keys.pb.h"
#include "gateway/command/base64.h"
#include "gateway/command/signing.h"

namespace fleetgw::command {
namespace {

constexpr std::array<std::string_view, 10> kDelegationActions{
    "lock",       "unlock",    "speed_limit", "assist_level", "headlight",
    "clear_trip", "power_off", "diagnostics", "zones",        "campaign"};

// A received string quoted in a detail (distinct name from verifier.cc's: unity builds). This
// library sits below fleetgw_common (common/untrusted_text.h), so the rule is a stricter local
// one: printable ASCII kept, quote, backslash and any other byte as \xNN, at most 64 bytes
// of input: always one line of ASCII.
std::string quote_delegation_text(std::string_view untrusted) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out = "'";
  for (const char ch : untrusted.substr(0, 64)) {
    const auto c = static_cast<unsigned char>(ch);
    if (c >= 0x20 && c < 0x7f && c != '\\' && c != '\'') {
      out += ch;
    } else {
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 0xf];
    }
  }
  if (untrusted.size() > 64) out += "...";
  return out + "'";
}

std::span<const std::uint8_t> bytes_of_text(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

DelegationProblem invalid_delegation(std::string detail) {
  return {DelegationRefusal::kInvalid, std::move(detail)};
}

RevocationVerdict refused_list(std::string reason, std::string detail, std::uint64_t version = 0) {
  RevocationVerdict v;
  v.reason = std::move(reason);
  v.detail = std::move(detail);
  v.version = version;
  return v;
}

std::string format_list_time(Micros t) {
  // Seconds are enough for a delegation's window; the verifier's format_utc() lives in
  // fleetgw_command, which this library must not depend on.
  const std::int64_t secs = t.count() / 1'000'000;
  const std::time_t tt = static_cast<std::time_t>(secs);
  std::tm tm{};
  if (gmtime_r(&tt, &tm) == nullptr) return std::to_string(t.count()) + "us";
  char buf[32];
  const std::size_t n = std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return std::string(buf, n);
}

}  // namespace

std::string_view delegation_refusal_name(DelegationRefusal reason) {
  switch (reason) {
    case DelegationRefusal::kInvalid:
      return "delegation_invalid";
    case DelegationRefusal::kRevoked:
      return "revoked";
    case DelegationRefusal::kOutOfScope:
      return "out_of_scope";
    case DelegationRefusal::kClockUnsynchronised:
      return "clock_unsynchronised";
    case DelegationRefusal::kNotYetValid:
      return "delegation_not_yet_valid";
    case DelegationRefusal::kExpired:
      return "delegation_expired";
  }
  return "delegation_invalid";
}

bool is_known_delegation_action(std::string_view action) {
  return std::find(kDelegationActions.begin(), kDelegationActions.end(), action) !=
         kDelegationActions.end();
}

std::string_view known_delegation_actions() {
  return "lock, unlock, speed_limit, assist_level, headlight, clear_trip, power_off, "
         "diagnostics, zones, campaign";
}

std::optional<std::string> delegation_content_problem(const v1::Delegation& d) {
  const std::string serial = "delegation " + std::to_string(d.serial());
  if (d.serial() == 0) return "delegation serial 0 (must be > 0)";
  if (!is_valid_tool_id(d.key_id())) {
    return std::optional<std::string>(serial + ": key id " + quote_delegation_text(d.key_id()) +
                                      " is not 1..64 characters of [A-Za-z0-9._-]");
  }
  if (d.public_key().size() != kEd25519PublicKeyBytes ||
      !Ed25519PublicKey::from_raw(bytes_of_text(d.public_key()))) {
    return serial + ": public_key is not a raw Ed25519 key (32 bytes)";
  }
  if (d.actions().empty()) return serial + " grants no action";
  if (d.vehicle_ids().empty() && d.groups().empty() && !d.all_vehicles()) {
    return serial + " names no vehicle, group or all_vehicles";
  }
  for (const auto& v : d.vehicle_ids()) {
    if (!is_valid_tool_id(v)) {
      return std::optional<std::string>(serial + ": vehicle id " + quote_delegation_text(v) +
                                        " is invalid");
    }
  }
  for (const auto& g : d.groups()) {
    if (!is_valid_tool_id(g)) {
      return serial + ": group " + quote_delegation_text(g) + " is invalid";
    }
  }
  if (d.not_before_us() <= 0 || d.not_after_us() <= d.not_before_us()) {
    return serial + ": needs 0 < not_before_us < not_after_us";
  }
  if (d.holder().size() > kMaxHolderBytes) {
    return std::optional<std::string>(serial + ": holder over " + std::to_string(kMaxHolderBytes) +
                                      " bytes");
  }
  return std::nullopt;
}

RootKeys::RootKeys(const std::map<std::string, std::string>& config) {
  for (const auto& [id, text] : config) {
    if (!is_valid_tool_id(id)) {
      throw std::invalid_argument("command.root_keys." + id +
                                  ": a key id is 1..64 characters of [A-Za-z0-9._-]");
    }
    auto key = Ed25519PublicKey::from_base64(text);
    if (!key) {
      throw std::invalid_argument("command.root_keys." + id +
                                  ": not a base64 raw Ed25519 public key (32 bytes)");
    }
    keys_.emplace(id, std::move(*key));
  }
}

const Ed25519PublicKey* RootKeys::find(std::string_view id) const {
  const auto it = keys_.find(id);
  return it == keys_.end() ? nullptr : &it->second;
}

std::variant<OpenedDelegation, DelegationProblem> RootKeys::open(
    const v1::SignedDelegation& sd, std::string_view signer_key_id) const {
  if (sd.root_key_id().empty()) return invalid_delegation("the delegation names no root key");
  const Ed25519PublicKey* root = find(sd.root_key_id());
  if (!root) {
    return invalid_delegation("root key " + quote_delegation_text(sd.root_key_id()) +
                              " is not in [command.root_keys]");
  }
  if (sd.delegation().empty()) return invalid_delegation("empty delegation bytes");
  if (!root->verify(bytes_of_text(sd.delegation()), bytes_of_text(sd.signature()))) {
    return invalid_delegation("the root signature of " + quote_delegation_text(sd.root_key_id()) +
                              " does not verify over the delegation bytes");
  }
  // Signed by the root from here on; what follows catches an issuer's mistake.
  v1::Delegation d;
  if (!d.ParseFromString(sd.delegation())) {
    return invalid_delegation("delegation bytes are not a fleetgw.v1.Delegation");
  }
  if (auto problem = delegation_content_problem(d)) return invalid_delegation(std::move(*problem));
  if (d.key_id() != signer_key_id) {
    return invalid_delegation("delegation " + std::to_string(d.serial()) + " is for key " +
                              quote_delegation_text(d.key_id()) + ", not for the signing key " +
                              quote_delegation_text(signer_key_id));
  }
  auto key = Ed25519PublicKey::from_raw(bytes_of_text(d.public_key()));
  if (!key) return invalid_delegation("public_key is not a raw Ed25519 key (32 bytes)");
  OpenedDelegation out{Grant{}, std::move(*key)};
  Grant& g = out.grant;
  g.root_key_id = sd.root_key_id();
  g.serial = d.serial();
  g.key_id = d.key_id();
  g.actions.assign(d.actions().begin(), d.actions().end());
  g.vehicle_ids.assign(d.vehicle_ids().begin(), d.vehicle_ids().end());
  g.groups.assign(d.groups().begin(), d.groups().end());
  g.all_vehicles = d.all_vehicles();
  g.not_before = Micros(d.not_before_us());
  g.not_after = Micros(d.not_after_us());
  g.holder = d.holder();  // for people: displayed escaped (keys show)
  return out;
}

std::optional<DelegationProblem> judge(const Grant& g, std::string_view action,
                                       const VehicleIdentity& vehicle, Micros now,
                                       bool clock_synchronised, const Revocations& revocations) {
  const std::string which =
      "delegation " + std::to_string(g.serial) + " of root '" + g.root_key_id + "'";
  if (auto why = revocations.revoked(g.root_key_id, g.serial, g.key_id)) {
    return DelegationProblem{DelegationRefusal::kRevoked, std::move(*why)};
  }
  if (std::find(g.actions.begin(), g.actions.end(), action) == g.actions.end()) {
    return DelegationProblem{DelegationRefusal::kOutOfScope,
                             "action '" + std::string(action) + "' is not granted by " + which};
  }
  const bool by_id =
      std::find(g.vehicle_ids.begin(), g.vehicle_ids.end(), vehicle.id) != g.vehicle_ids.end();
  const bool by_group = std::any_of(g.groups.begin(), g.groups.end(), [&](const std::string& x) {
    return std::find(vehicle.groups.begin(), vehicle.groups.end(), x) != vehicle.groups.end();
  });
  if (!g.all_vehicles && !by_id && !by_group) {
    return DelegationProblem{DelegationRefusal::kOutOfScope,
                             "vehicle '" + vehicle.id + "' (groups: " +
                                 (vehicle.groups.empty() ? std::string("none") : [&] {
                                   std::string s;
                                   for (const auto& x : vehicle.groups) s += (s.empty() ? "" : ", ") + x;
                                   return s;
                                 }()) +
                                 ") is not in the scope of " + which};
  }
  if (!clock_synchronised) {
    return DelegationProblem{
        DelegationRefusal::kClockUnsynchronised,
        "wall clock not synchronised: the window of " + which + " cannot be judged"};
  }
  if (now < g.not_before) {
    return DelegationProblem{DelegationRefusal::kNotYetValid, which + " is valid from " +
                                                                  format_list_time(g.not_before) +
                                                                  ", now " + format_list_time(now)};
  }
  if (now >= g.not_after) {
    return DelegationProblem{
        DelegationRefusal::kExpired,
        which + " expired at " + format_list_time(g.not_after) + ", now " + format_list_time(now)};
  }
  return std::nullopt;
}

DelegatedCheck check_delegated(const v1::SignedDelegation& sd, std::string_view signer_key_id,
                               std::span<const std::uint8_t> signed_bytes,
                               std::span<const std::uint8_t> signature, std::string_view action,
                               const VehicleIdentity& vehicle, Micros now, bool clock_synchronised,
                               const RootKeys& roots, const Revocations& revocations) {
  DelegatedCheck out;
  auto opened = roots.open(sd, signer_key_id);
  if (auto* p = std::get_if<DelegationProblem>(&opened)) {
    out.problem = std::move(*p);
    return out;
  }
  auto& od = std::get<OpenedDelegation>(opened);
  if (!od.public_key.verify(signed_bytes, signature)) {
    out.signature_invalid = true;
    return out;
  }
  out.problem = judge(od.grant, action, vehicle, now, clock_synchronised, revocations);
  out.grant = std::move(od.grant);
  return out;
}

std::string sign_delegation(const v1::Delegation& delegation, const Ed25519PrivateKey& root,
                            std::string_view root_key_id) {
  v1::SignedDelegation s;
  s.set_delegation(delegation.SerializeAsString());
  const auto sig = root.sign(bytes_of_text(s.delegation()));
  s.set_signature(std::string(sig.begin(), sig.end()));
  s.set_root_key_id(std::string(root_key_id));
  return s.SerializeAsString();
}

std::string sign_revocation_list(const v1::RevocationList& list, const Ed25519PrivateKey& root,
                                 std::string_view root_key_id) {
  v1::SignedRevocationList s;
  s.set_revocations(list.SerializeAsString());
  const auto sig = root.sign(bytes_of_text(s.revocations()));
  s.set_signature(std::string(sig.begin(), sig.end()));
  s.set_root_key_id(std::string(root_key_id));
  return s.SerializeAsString();
}

// --- revocation lists ---------------------------------------------------------------------------

RevocationVerdict Revocations::offer(std::span<const std::uint8_t> payload, const RootKeys& roots) {
  if (payload.size() > kMaxRevocationBytes) {
    return refused_list("too_large", "payload of " + std::to_string(payload.size()) +
                                         " bytes exceeds " + std::to_string(kMaxRevocationBytes));
  }
  v1::SignedRevocationList sl;
  if (!sl.ParseFromArray(payload.data(), static_cast<int>(payload.size()))) {
    return refused_list("malformed", "not a fleetgw.v1.SignedRevocationList");
  }
  if (sl.revocations().empty() || sl.signature().empty() || sl.root_key_id().empty()) {
    return refused_list("malformed", "needs revocations, signature and root_key_id");
  }
  const Ed25519PublicKey* root = roots.find(sl.root_key_id());
  if (!root) {
    return refused_list("unknown_key", "root key " + quote_delegation_text(sl.root_key_id()) +
                                           " is not in [command.root_keys]");
  }
  if (!root->verify(bytes_of_text(sl.revocations()), bytes_of_text(sl.signature()))) {
    return refused_list("signature_invalid", "the signature of root " +
                                                 quote_delegation_text(sl.root_key_id()) +
                                                 " does not verify over the list bytes");
  }
  v1::RevocationList list;
  if (!list.ParseFromString(sl.revocations())) {
    return refused_list("malformed", "list bytes are not a fleetgw.v1.RevocationList");
  }
  if (list.version() == 0 || list.issued_at_us() <= 0) {
    return refused_list("malformed", "version and issued_at_us must be > 0");
  }
  for (const auto& k : list.revoked_key_ids()) {
    if (!is_valid_tool_id(k)) {
      return refused_list("malformed",
                          "revoked key id " + quote_delegation_text(k) +
                              " is not 1..64 characters of [A-Za-z0-9._-]",
                          list.version());
    }
  }
  std::string text(reinterpret_cast<const char*>(payload.data()), payload.size());
  if (const auto it = lists_.find(sl.root_key_id()); it != lists_.end()) {
    const std::uint64_t held = it->second.version;
    if (list.version() == held && text == it->second.payload) {
      RevocationVerdict v;
      v.outcome = RevocationOutcome::kAlreadyInForce;
      v.detail = "version " + std::to_string(held) + " is already in force";
      v.version = held;
      return v;
    }
    if (list.version() == held) {
      return refused_list("version_conflict",
                          "version " + std::to_string(held) +
                              " is in force with different content; a change needs a new version",
                          held);
    }
    if (list.version() < held) {
      return refused_list("not_newer",
                          "version " + std::to_string(list.version()) + " is older than version " +
                              std::to_string(held) + " in force",
                          list.version());
    }
  }
  RevocationEntry e;
  e.version = list.version();
  e.issued_at_us = list.issued_at_us();
  e.serials.insert(list.revoked_serials().begin(), list.revoked_serials().end());
  e.key_ids.insert(list.revoked_key_ids().begin(), list.revoked_key_ids().end());
  e.payload = std::move(text);
  RevocationVerdict v;
  v.outcome = RevocationOutcome::kAccepted;
  v.version = e.version;
  v.detail = "version " + std::to_string(e.version) + " of root '" + sl.root_key_id() +
             "' in force: " + std::to_string(e.serials.size()) + " serial(s), " +
             std::to_string(e.key_ids.size()) + " key id(s) revoked";
  lists_[sl.root_key_id()] = std::move(e);
  unknown_.reset();  // a root's list again: the fail-closed state ends
  return v;
}

std::optional<std::string> Revocations::revoked(std::string_view root_key_id, std::uint64_t serial,
                                                std::string_view key_id) const {
  if (unknown_ && !root_key_id.empty()) {
    return "the stored revocation lists could not be restored (" + *unknown_ +
           "): delegated keys are refused until a root's list is received";
  }
  if (!root_key_id.empty()) {
    if (const auto it = lists_.find(root_key_id);
        it != lists_.end() && it->second.serials.count(serial) != 0) {
      return "delegation " + std::to_string(serial) + " of root '" + std::string(root_key_id) +
             "' is revoked by revocation list version " + std::to_string(it->second.version);
    }
  }
  // A key id revoked by any root: a revocation is never narrower than the revoker meant.
  for (const auto& [root, entry] : lists_) {
    if (entry.key_ids.count(key_id) != 0) {
      return "key " + quote_delegation_text(key_id) + " is revoked by revocation list version " +
             std::to_string(entry.version) + " of root '" + root + "'";
    }
  }
  return std::nullopt;
}

std::uint64_t Revocations::version() const {
  std::uint64_t v = 0;
  for (const auto& [root, entry] : lists_) v = std::max(v, entry.version);
  return v;
}

std::string Revocations::persisted() const {
  std::string out;
  for (const auto& [root, entry] : lists_) {
    out += encode_base64(bytes_of_text(entry.payload));
    out += '\n';
  }
  return out;
}

std::vector<std::string> Revocations::restore(std::string_view text, const RootKeys& roots) {
  std::vector<std::string> problems;
  std::size_t line_no = 0;
  while (!text.empty()) {
    const std::size_t nl = text.find('\n');
    const std::string_view line = text.substr(0, nl);
    text = nl == std::string_view::npos ? std::string_view{} : text.substr(nl + 1);
    ++line_no;
    if (line.empty()) continue;
    const auto raw = decode_base64(line);
    if (!raw) {
      problems.push_back("stored list " + std::to_string(line_no) + ": not base64");
      unknown_ = problems.back();
      continue;
    }
    const auto v = offer(*raw, roots);
    if (v.outcome == RevocationOutcome::kRefused) {
      problems.push_back("stored list " + std::to_string(line_no) + ": " + v.reason + ": " +
                         v.detail);
      // A root removed from the configuration takes its list with it; anything else means the
      // stored text is not what this gateway wrote.
      if (v.reason != "unknown_key") unknown_ = problems.back();
    }
  }
  return problems;
}

}  // namespace fleetgw::command
