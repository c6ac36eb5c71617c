#include "gateway/tools/operator/keys_tool.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "fleetgw/v1/keys.pb.h"
#include "gateway/command/base64.h"
#include "gateway/command/delegation.h"
#include "gateway/command/ed25519.h"
#include "gateway/command/signing.h"
#include "gateway/common/untrusted_text.h"
#include "gateway/tools/common/time_arg.h"

namespace fleetgw::tools {
namespace {

namespace fs = std::filesystem;
using command::Ed25519PrivateKey;
using command::Ed25519PublicKey;

constexpr int kKeysOk = 0;
constexpr int kKeysFailed = 1;
constexpr int kKeysUsage = 2;

// Creates `file` with `bytes`; never replaces an existing file (O_EXCL).
void write_new_file(const fs::path& file, std::string_view bytes, mode_t mode = 0644) {
  const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, mode);
  if (fd < 0) throw std::runtime_error(file.string() + ": " + std::strerror(errno));
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int e = errno;
      ::close(fd);
      ::unlink(file.c_str());
      throw std::runtime_error(file.string() + ": write failed: " + std::strerror(e));
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    throw std::runtime_error(file.string() + ": write failed: " + std::strerror(errno));
  }
}

std::optional<std::string> read_whole_file(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return std::nullopt;
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string join_list(const auto& items) {
  if (items.empty()) return "-";
  std::ostringstream s;
  bool first = true;
  for (const auto& x : items) {
    s << (first ? "" : ", ") << x;
    first = false;
  }
  return s.str();
}

std::string shown(std::string_view untrusted) {
  return common::untrusted_excerpt(untrusted, 128);
}

// An absolute ISO 8601 UTC time (relative forms of --since mean "before now": not for here).
std::optional<Micros> parse_time(std::string_view text) {
  if (text.find('-') == std::string_view::npos) return std::nullopt;
  const auto us = parse_since(text, 0);
  if (!us) return std::nullopt;
  return Micros(*us);
}

// The root's private key and its id, or a usage error on `err`.
std::optional<Ed25519PrivateKey> load_root(const fs::path& pem, const std::string& id,
                                           std::ostream& err, std::string_view tool) {
  if (!command::is_valid_tool_id(id)) {
    err << tool << ": --root-id: 1..64 characters of [A-Za-z0-9._-]\n";
    return std::nullopt;
  }
  try {
    return Ed25519PrivateKey::load_pem(pem);
  } catch (const std::exception& e) {
    err << tool << ": --root: " << e.what() << '\n';
    return std::nullopt;
  }
}

// The delegate's public key from --public-key (a .pub file or the base64 text).
std::optional<Ed25519PublicKey> read_public_key(const std::string& arg) {
  std::string text = arg;
  if (std::error_code ec; fs::is_regular_file(arg, ec)) {
    if (auto content = read_whole_file(arg)) text = *content;
  }
  return Ed25519PublicKey::from_base64(text);
}

std::string describe_delegation(const v1::Delegation& d) {
  std::ostringstream s;
  s << "delegation serial " << d.serial() << " for key '" << shown(d.key_id()) << "'\n";
  const std::string raw = d.public_key();
  s << "  public key  "
    << command::encode_base64({reinterpret_cast<const std::uint8_t*>(raw.data()), raw.size()})
    << '\n';
  s << "  holder      " << (d.holder().empty() ? "-" : shown(d.holder())) << '\n';
  std::vector<std::string> actions, vehicles, groups;
  for (const auto& a : d.actions()) actions.push_back(shown(a));
  for (const auto& v : d.vehicle_ids()) vehicles.push_back(shown(v));
  for (const auto& g : d.groups()) groups.push_back(shown(g));
  s << "  actions     " << join_list(actions) << '\n';
  s << "  vehicles    " << (d.all_vehicles() ? "all vehicles" : join_list(vehicles)) << '\n';
  s << "  groups      " << join_list(groups) << '\n';
  s << "  valid       " << iso_utc(d.not_before_us()) << " .. " << iso_utc(d.not_after_us())
    << " (from not_before, up to but not including not_after)\n";
  s << "  issued      " << iso_utc(d.issued_at_us()) << '\n';
  return s.str();
}

}  // namespace

int run_keys_root(const KeysRootOptions& o, std::ostream& out, std::ostream& err) {
  const std::string id = o.key_id.empty() ? o.out_prefix.filename().string() : o.key_id;
  if (!command::is_valid_tool_id(id)) {
    err << "keys root: key id '" << shown(id) << "' must be 1..64 characters of [A-Za-z0-9._-]\n";
    return kKeysUsage;
  }
  try {
    const fs::path pem = o.out_prefix.string() + ".pem";
    const fs::path pub = o.out_prefix.string() + ".pub";
    if (fs::exists(pub)) {
      err << "keys root: " << pub.string() << " exists; not overwritten\n";
      return kKeysFailed;
    }
    const auto key = Ed25519PrivateKey::generate();
    key.write_pem(pem);  // 0600, never overwrites
    const std::string pub64 = key.public_key().base64();
    write_new_file(pub, pub64 + "\n");
    err << "keys root: private key " << pem.string() << " (mode 0600: keep it offline), public key "
        << pub.string() << "\nkeys root: add this line to [command.root_keys] of the gateways:\n";
    out << id << " = \"" << pub64 << "\"\n";
    return kKeysOk;
  } catch (const std::exception& e) {
    err << "keys root: " << e.what() << '\n';
    return kKeysFailed;
  }
}

int run_keys_delegate(const KeysDelegateOptions& o, std::ostream& out, std::ostream& err) {
  auto usage = [&](const std::string& what) {
    err << "keys delegate: " << what << '\n';
    return kKeysUsage;
  };
  if (!command::is_valid_tool_id(o.key_id)) {
    return usage("--key-id: 1..64 characters of [A-Za-z0-9._-]");
  }
  if (o.public_key.empty() == o.new_key_prefix.empty()) {
    return usage("give exactly one of --public-key and --new-key");
  }
  if (o.actions.empty()) return usage("--actions: at least one action");
  for (const auto& a : o.actions) {
    if (!command::is_known_delegation_action(a)) {
      return usage("--actions: '" + shown(a) + "' is not one of " +
                   std::string(command::known_delegation_actions()));
    }
  }
  if (o.all_vehicles && (!o.vehicles.empty() || !o.groups.empty())) {
    return usage("--all-vehicles goes alone, without --vehicles or --groups");
  }
  if (!o.all_vehicles && o.vehicles.empty() && o.groups.empty()) {
    return usage("give --vehicles, --groups or --all-vehicles (never implied)");
  }
  for (const auto& v : o.vehicles) {
    if (!command::is_valid_tool_id(v)) {
      return usage("--vehicles: '" + shown(v) + "' is not 1..64 of [A-Za-z0-9._-]");
    }
  }
  for (const auto& g : o.groups) {
    if (!command::is_valid_tool_id(g)) {
      return usage("--groups: '" + shown(g) + "' is not 1..64 of [A-Za-z0-9._-]");
    }
  }
  if (o.serial == 0) return usage("--serial: > 0 (unique per root: a revocation list names it)");
  if (o.holder.size() > command::kMaxHolderBytes) return usage("--holder: at most 128 bytes");
  const auto not_after = parse_time(o.not_after);
  if (!not_after) return usage("--not-after: an ISO 8601 UTC time, e.g. 2027-01-01T00:00:00Z");
  Micros not_before = o.now;
  if (!o.not_before.empty()) {
    const auto t = parse_time(o.not_before);
    if (!t) return usage("--not-before: an ISO 8601 UTC time, e.g. 2026-12-01T00:00:00Z");
    not_before = *t;
  }
  if (not_before.count() <= 0 || *not_after <= not_before) {
    return usage("--not-after must be later than --not-before (" + iso_utc(not_before.count()) +
                 ")");
  }
  if (fs::exists(o.out)) {
    err << "keys delegate: " << o.out.string() << " exists; not overwritten\n";
    return kKeysFailed;
  }
  const auto root = load_root(o.root_pem, o.root_id, err, "keys delegate");
  if (!root) return kKeysUsage;

  std::optional<Ed25519PublicKey> delegate_key;
  if (!o.public_key.empty()) {
    delegate_key = read_public_key(o.public_key);
    if (!delegate_key) {
      return usage("--public-key: neither a .pub file nor a base64 raw Ed25519 public key");
    }
  }
  try {
    if (!o.new_key_prefix.empty()) {
      const fs::path pem = o.new_key_prefix.string() + ".pem";
      const fs::path pub = o.new_key_prefix.string() + ".pub";
      if (fs::exists(pub)) {
        err << "keys delegate: " << pub.string() << " exists; not overwritten\n";
        return kKeysFailed;
      }
      const auto fresh = Ed25519PrivateKey::generate();
      fresh.write_pem(pem);
      write_new_file(pub, fresh.public_key().base64() + "\n");
      delegate_key = fresh.public_key();
      err << "keys delegate: the delegate's private key " << pem.string()
          << " (mode 0600: for its holder only), public key " << pub.string() << '\n';
    }
    v1::Delegation d;
    d.set_serial(o.serial);
    d.set_key_id(o.key_id);
    const auto& raw = delegate_key->raw();
    d.set_public_key(std::string(raw.begin(), raw.end()));
    for (const auto& a : o.actions) d.add_actions(a);
    for (const auto& v : o.vehicles) d.add_vehicle_ids(v);
    for (const auto& g : o.groups) d.add_groups(g);
    d.set_all_vehicles(o.all_vehicles);
    d.set_not_before_us(not_before.count());
    d.set_not_after_us(not_after->count());
    d.set_issued_at_us(o.now.count());
    d.set_holder(o.holder);
    const std::string file = command::sign_delegation(d, *root, o.root_id);
    // Judged by the gateway's own code before it leaves this tool.
    const command::RootKeys roots(
        std::map<std::string, std::string>{{o.root_id, root->public_key().base64()}});
    v1::SignedDelegation sd;
    sd.ParseFromString(file);
    auto opened = roots.open(sd, o.key_id);
    if (const auto* p = std::get_if<command::DelegationProblem>(&opened)) {
      err << "keys delegate: the gateway would refuse it: " << p->detail << '\n';
      return kKeysFailed;
    }
    write_new_file(o.out, file);
    out << describe_delegation(d) << "  signed by   root '" << o.root_id << "' -> "
        << o.out.string() << '\n';
    return kKeysOk;
  } catch (const std::exception& e) {
    err << "keys delegate: " << e.what() << '\n';
    return kKeysFailed;
  }
}

int run_keys_revoke(const KeysRevokeOptions& o, std::ostream& out, std::ostream& err) {
  auto usage = [&](const std::string& what) {
    err << "keys revoke: " << what << '\n';
    return kKeysUsage;
  };
  if (o.version == 0) return usage("--version: > 0, greater than the list the gateways hold");
  for (const auto s : o.serials) {
    if (s == 0) return usage("--serial: > 0");
  }
  for (const auto& k : o.key_ids) {
    if (!command::is_valid_tool_id(k)) {
      return usage("--key-id: '" + shown(k) + "' is not 1..64 of [A-Za-z0-9._-]");
    }
  }
  if (fs::exists(o.out)) {
    err << "keys revoke: " << o.out.string() << " exists; not overwritten\n";
    return kKeysFailed;
  }
  const auto root = load_root(o.root_pem, o.root_id, err, "keys revoke");
  if (!root) return kKeysUsage;
  if (o.serials.empty() && o.key_ids.empty()) {
    err << "keys revoke: note: an empty list lifts every earlier revocation of this root\n";
  }
  try {
    v1::RevocationList list;
    list.set_version(o.version);
    list.set_issued_at_us(o.now.count());
    for (const auto s : o.serials) list.add_revoked_serials(s);
    for (const auto& k : o.key_ids) list.add_revoked_key_ids(k);
    write_new_file(o.out, command::sign_revocation_list(list, *root, o.root_id));
    out << "revocation list version " << o.version << " of root '" << o.root_id << "': serials "
        << join_list(o.serials) << "; key ids " << join_list(o.key_ids) << " -> " << o.out.string()
        << '\n';
    return kKeysOk;
  } catch (const std::exception& e) {
    err << "keys revoke: " << e.what() << '\n';
    return kKeysFailed;
  }
}

int run_keys_show(const KeysShowOptions& o, std::ostream& out, std::ostream& err) {
  const auto bytes = read_whole_file(o.file);
  if (!bytes) {
    err << "keys show: cannot read " << o.file.string() << '\n';
    return kKeysFailed;
  }
  std::optional<command::RootKeys> roots;
  if (o.check_signature) {
    try {
      roots.emplace(o.root_keys);
    } catch (const std::exception& e) {
      err << "keys show: " << e.what() << '\n';
      return kKeysFailed;
    }
  }
  // Both signed forms are (bytes, bytes, string): the inner message tells them apart.
  v1::SignedDelegation sd;
  v1::Delegation d;
  if (sd.ParseFromString(*bytes) && !sd.delegation().empty() &&
      d.ParseFromString(sd.delegation()) && !d.key_id().empty() && d.public_key().size() == 32) {
    out << describe_delegation(d) << "  root        '" << shown(sd.root_key_id()) << "'\n";
    // The gateway's own rules: with the roots, exactly what a gateway opens; without, the
    // contents alone.
    std::optional<std::string> problem;
    if (roots) {
      auto opened = roots->open(sd, d.key_id());
      if (auto* p = std::get_if<command::DelegationProblem>(&opened)) problem = p->detail;
    } else {
      problem = command::delegation_content_problem(d);
    }
    if (problem) {
      out << "  INVALID     " << *problem << '\n';
      return kKeysFailed;
    }
    if (roots) {
      out << "  signature   valid (root '" << shown(sd.root_key_id()) << "')\n";
    } else {
      out << "  signature   not checked (give --config with [command.root_keys])\n";
    }
    const Micros now = o.now;
    const char* state = now.count() < d.not_before_us()   ? "not yet valid"
                        : now.count() >= d.not_after_us() ? "expired"
                                                          : "valid now";
    out << "  state       " << state << " (" << iso_utc(now.count()) << ")\n";
    return kKeysOk;
  }
  v1::SignedRevocationList sl;
  v1::RevocationList list;
  if (sl.ParseFromString(*bytes) && !sl.revocations().empty() &&
      list.ParseFromString(sl.revocations()) && list.version() > 0 && list.issued_at_us() > 0) {
    std::vector<std::string> keys;
    for (const auto& k : list.revoked_key_ids()) keys.push_back(shown(k));
    std::vector<std::uint64_t> serials(list.revoked_serials().begin(),
                                       list.revoked_serials().end());
    out << "revocation list version " << list.version() << " of root '" << shown(sl.root_key_id())
        << "'\n"
        << "  issued      " << iso_utc(list.issued_at_us()) << '\n'
        << "  serials     " << join_list(serials) << '\n'
        << "  key ids     " << join_list(keys) << '\n';
    if (!roots) {
      out << "  signature   not checked (give --config with [command.root_keys])\n";
      return kKeysOk;
    }
    command::Revocations judge;
    const auto v =
        judge.offer({reinterpret_cast<const std::uint8_t*>(bytes->data()), bytes->size()}, *roots);
    if (!v.accepted()) {
      out << "  INVALID     " << v.reason << ": " << v.detail << '\n';
      return kKeysFailed;
    }
    out << "  signature   valid (root '" << shown(sl.root_key_id()) << "')\n";
    return kKeysOk;
  }
  err << "keys show: " << o.file.string()
      << " is neither a signed delegation nor a signed revocation list\n";
  return kKeysFailed;
}

}  // namespace fleetgw::tools
