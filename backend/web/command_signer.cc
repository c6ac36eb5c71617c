// Signing commands under the console's delegation (command_signer.h).
#include "backend/web/command_signer.h"

#include <openssl/evp.h>
#include <openssl/pem.h>
#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "backend/web/secrets.h"
#include "fleetgw/v1/command.pb.h"
#include "fleetgw/v1/keys.pb.h"

namespace fleetgw::web {

// Named, not anonymous: CommandSigner::Impl (external linkage) holds a key with this deleter,
// and gcc's -Wsubobject-linkage refuses anonymous-namespace members there in a unity build.
namespace signer_detail {
struct PkeyFree {
  void operator()(EVP_PKEY* k) const { EVP_PKEY_free(k); }
};
}  // namespace signer_detail
using signer_detail::PkeyFree;

namespace {

using nlohmann::json;

struct MdCtxFree {
  void operator()(EVP_MD_CTX* c) const { EVP_MD_CTX_free(c); }
};
struct FileClose {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

constexpr std::string_view kActions[] = {"lock",      "unlock",     "speed_limit", "assist_level",
                                         "headlight", "clear_trip", "power_off"};

// Lock kinds and assist names travel to the bike and into reasons: keep them plain.
bool plain_name(std::string_view s) {
  if (s.empty() || s.size() > 32) return false;
  return std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
  });
}

std::string read_file_bytes(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error("--delegation " + file.string() + ": cannot be read");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string utc(std::int64_t us) {
  const std::time_t t = static_cast<std::time_t>(us / 1'000'000);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

}  // namespace

std::string hex_bytes(std::string_view bytes) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  out.reserve(bytes.size() * 2);
  for (const char ch : bytes) {
    const auto b = static_cast<unsigned char>(ch);
    out += kHex[b >> 4];
    out += kHex[b & 15];
  }
  return out;
}

std::string CommandRequest::summary() const {
  if (action == "lock" || action == "unlock") {
    return action + " " + (lock_kind.empty() ? std::string("whole vehicle") : lock_kind);
  }
  if (action == "speed_limit") return "speed_limit " + std::to_string(kmh) + " km/h";
  if (action == "assist_level") return "assist_level " + level;
  if (action == "headlight") return std::string("headlight ") + (on ? "on" : "off");
  return action;
}

std::variant<CommandRequest, std::string> parse_command_request(const json& body) {
  if (!body.is_object() || !body.contains("action") || !body["action"].is_string()) {
    return std::string("expected {\"action\": \"lock\"|\"unlock\"|\"speed_limit\"|...}");
  }
  CommandRequest r;
  r.action = body["action"].get<std::string>();
  if (std::find(std::begin(kActions), std::end(kActions), r.action) == std::end(kActions)) {
    return "unknown action (lock, unlock, speed_limit, assist_level, headlight, clear_trip, "
           "power_off)";
  }
  if (r.action == "lock" || r.action == "unlock") {
    if (body.contains("lock_kind") && !body["lock_kind"].is_null()) {
      if (!body["lock_kind"].is_string() || !plain_name(body["lock_kind"].get<std::string>())) {
        return std::string("lock_kind: 1-32 of [a-z0-9_] (omit it for the whole vehicle)");
      }
      r.lock_kind = body["lock_kind"].get<std::string>();
    }
  } else if (r.action == "speed_limit") {
    if (!body.contains("kmh") || !body["kmh"].is_number_integer() || body["kmh"].get<int>() < 1 ||
        body["kmh"].get<int>() > 255) {
      return std::string("speed_limit needs kmh, an integer 1..255");
    }
    r.kmh = body["kmh"].get<std::uint32_t>();
  } else if (r.action == "assist_level") {
    if (!body.contains("level") || !body["level"].is_string() ||
        !plain_name(body["level"].get<std::string>())) {
      return std::string("assist_level needs level, 1-32 of [a-z0-9_] (eco, sport, ...)");
    }
    r.level = body["level"].get<std::string>();
  } else if (r.action == "headlight") {
    if (!body.contains("on") || !body["on"].is_boolean())
      return std::string("headlight needs on: true|false");
    r.on = body["on"].get<bool>();
  }
  return r;
}

struct CommandSigner::Impl {
  std::unique_ptr<EVP_PKEY, PkeyFree> key;
  std::optional<v1::SignedDelegation> signed_delegation;
  v1::Delegation delegation;
};

CommandSigner::CommandSigner(const std::filesystem::path& key_file,
                             const std::filesystem::path& delegation_file, std::string key_id)
    : impl_(std::make_unique<Impl>()), key_id_(std::move(key_id)) {
  const std::string kf = key_file.string();
  struct stat st {};
  if (::stat(kf.c_str(), &st) != 0) throw std::runtime_error("--signing-key " + kf + ": not found");
  // A signing key the group or others can read is a fleet's worth of commands for anyone on
  // the host: refused, as ssh refuses such a private key.
  if ((st.st_mode & 077) != 0) {
    throw std::runtime_error("--signing-key " + kf +
                             ": readable or writable by its group or others (chmod 600 it)");
  }
  const std::unique_ptr<std::FILE, FileClose> f(std::fopen(kf.c_str(), "rb"));
  if (!f) throw std::runtime_error("--signing-key " + kf + ": cannot be read");
  impl_->key.reset(PEM_read_PrivateKey(f.get(), nullptr, nullptr, nullptr));
  if (!impl_->key || EVP_PKEY_id(impl_->key.get()) != EVP_PKEY_ED25519) {
    throw std::runtime_error("--signing-key " + kf +
                             ": not a PEM Ed25519 private key (fleetgw keygen writes one)");
  }
  if (!delegation_file.empty()) {
    const std::string df = delegation_file.string();
    v1::SignedDelegation sd;
    if (!sd.ParseFromString(read_file_bytes(delegation_file)) || sd.delegation().empty() ||
        sd.signature().empty() || !impl_->delegation.ParseFromString(sd.delegation())) {
      throw std::runtime_error("--delegation " + df +
                               ": not a serialized fleetgw.v1.SignedDelegation");
    }
    unsigned char pub[32];
    std::size_t len = sizeof pub;
    if (EVP_PKEY_get_raw_public_key(impl_->key.get(), pub, &len) != 1 || len != 32 ||
        impl_->delegation.public_key() != std::string(reinterpret_cast<char*>(pub), 32)) {
      throw std::runtime_error("--delegation " + df + " delegates key '" +
                               impl_->delegation.key_id() + "', whose public key is not that of " +
                               "--signing-key " + kf);
    }
    key_id_ = impl_->delegation.key_id();
    impl_->signed_delegation = std::move(sd);
  }
  if (key_id_.empty()) throw std::runtime_error("--signing-key " + kf + ": no key id");
}

CommandSigner::~CommandSigner() = default;

std::optional<std::uint64_t> CommandSigner::delegation_serial() const {
  if (!impl_->signed_delegation) return std::nullopt;
  return impl_->delegation.serial();
}

std::optional<std::string> CommandSigner::out_of_scope(const CommandRequest& r,
                                                       std::string_view vehicle_id,
                                                       std::int64_t now_us) const {
  if (!impl_->signed_delegation) return std::nullopt;
  const v1::Delegation& d = impl_->delegation;
  const std::string serial =
      "delegation " + std::to_string(d.serial()) + " of key '" + d.key_id() + "'";
  if (std::find(d.actions().begin(), d.actions().end(), r.action) == d.actions().end()) {
    return "action '" + r.action + "' is not delegated to this server (" + serial + ")";
  }
  const bool named = std::find(d.vehicle_ids().begin(), d.vehicle_ids().end(), vehicle_id) !=
                     d.vehicle_ids().end();
  if (!d.all_vehicles() && !named && d.groups_size() == 0) {
    return "vehicle not in the scope of this server's " + serial;
  }
  if (now_us < d.not_before_us()) return serial + " is valid from " + utc(d.not_before_us());
  if (now_us >= d.not_after_us()) return serial + " expired at " + utc(d.not_after_us());
  return std::nullopt;
}

SignedCommandBytes CommandSigner::sign(const CommandRequest& r, std::string_view vehicle_id,
                                       std::string_view operator_id, std::int64_t now_us,
                                       std::chrono::seconds ttl) const {
  v1::Command c;
  // 128 random bits, URL- and topic-safe: the bike refuses a reused id.
  c.set_command_id("c-" + random_token(16));
  c.set_vehicle_id(std::string(vehicle_id));
  c.set_issued_at_us(now_us);
  std::int64_t expires = now_us + std::chrono::microseconds(ttl).count();
  if (impl_->signed_delegation) expires = std::min(expires, impl_->delegation.not_after_us());
  c.set_expires_at_us(expires);
  c.set_operator_id(std::string(operator_id));
  if (r.action == "lock" || r.action == "unlock") {
    c.set_action(r.action == "lock" ? v1::COMMAND_ACTION_LOCK : v1::COMMAND_ACTION_UNLOCK);
    if (r.lock_kind.empty()) {
      c.set_whole_vehicle(true);
    } else {
      c.set_lock_kind(r.lock_kind);
    }
  } else if (r.action == "speed_limit") {
    c.mutable_speed_limit()->set_kmh(r.kmh);
  } else if (r.action == "assist_level") {
    c.mutable_assist_level()->set_level(r.level);
  } else if (r.action == "headlight") {
    c.mutable_headlight()->set_on(r.on);
  } else if (r.action == "clear_trip") {
    c.mutable_clear_trip();
  } else if (r.action == "power_off") {
    c.mutable_power_off();
  }
  const std::string bytes = c.SerializeAsString();

  // Ed25519 (pure, RFC 8032) over exactly the serialized Command.
  const std::unique_ptr<EVP_MD_CTX, MdCtxFree> ctx(EVP_MD_CTX_new());
  unsigned char sig[64];
  std::size_t sig_len = sizeof sig;
  if (!ctx || EVP_DigestSignInit(ctx.get(), nullptr, nullptr, nullptr, impl_->key.get()) != 1 ||
      EVP_DigestSign(ctx.get(), sig, &sig_len, reinterpret_cast<const unsigned char*>(bytes.data()),
                     bytes.size()) != 1 ||
      sig_len != 64) {
    throw std::runtime_error("Ed25519 signing failed (OpenSSL)");
  }
  v1::SignedCommand sc;
  sc.set_command(bytes);
  sc.set_signature(std::string(reinterpret_cast<char*>(sig), sig_len));
  sc.set_key_id(key_id_);
  if (impl_->signed_delegation) *sc.mutable_delegation() = *impl_->signed_delegation;

  SignedCommandBytes out;
  out.command_id = c.command_id();
  out.payload = sc.SerializeAsString();
  out.command_sha256 = sha256_hex(bytes);
  out.payload_sha256 = sha256_hex(out.payload);
  out.issued_at_us = now_us;
  out.expires_at_us = expires;
  return out;
}

std::string CommandSigner::sign_document(std::string_view bytes) const {
  const std::unique_ptr<EVP_MD_CTX, MdCtxFree> ctx(EVP_MD_CTX_new());
  unsigned char sig[64];
  std::size_t sig_len = sizeof sig;
  if (!ctx || EVP_DigestSignInit(ctx.get(), nullptr, nullptr, nullptr, impl_->key.get()) != 1 ||
      EVP_DigestSign(ctx.get(), sig, &sig_len, reinterpret_cast<const unsigned char*>(bytes.data()),
                     bytes.size()) != 1 ||
      sig_len != 64) {
    throw std::runtime_error("Ed25519 signing failed (OpenSSL)");
  }
  return std::string(reinterpret_cast<char*>(sig), sig_len);
}

const v1::SignedDelegation* CommandSigner::signed_delegation() const {
  return impl_->signed_delegation ? &*impl_->signed_delegation : nullptr;
}

std::optional<std::string> CommandSigner::document_out_of_scope(std::string_view action,
                                                                std::int64_t now_us) const {
  if (!impl_->signed_delegation) return std::nullopt;
  const v1::Delegation& d = impl_->delegation;
  const std::string serial =
      "delegation " + std::to_string(d.serial()) + " of key '" + d.key_id() + "'";
  if (std::find(d.actions().begin(), d.actions().end(), action) == d.actions().end()) {
    return "action '" + std::string(action) + "' is not delegated to this server (" + serial + ")";
  }
  if (now_us < d.not_before_us()) return serial + " is valid from " + utc(d.not_before_us());
  if (now_us >= d.not_after_us()) return serial + " expired at " + utc(d.not_after_us());
  return std::nullopt;
}

json CommandSigner::describe() const {
  json j = {{"key_id", key_id_}, {"delegated", impl_->signed_delegation.has_value()}};
  if (impl_->signed_delegation) {
    const v1::Delegation& d = impl_->delegation;
    j["serial"] = d.serial();
    j["actions"] = std::vector<std::string>(d.actions().begin(), d.actions().end());
    j["vehicle_ids"] = std::vector<std::string>(d.vehicle_ids().begin(), d.vehicle_ids().end());
    j["groups"] = std::vector<std::string>(d.groups().begin(), d.groups().end());
    j["all_vehicles"] = d.all_vehicles();
    j["not_before_us"] = d.not_before_us();
    j["not_after_us"] = d.not_after_us();
    j["holder"] = d.holder();
  } else {
    j["actions"] = std::vector<std::string>(std::begin(kActions), std::end(kActions));
    j["all_vehicles"] = true;
  }
  return j;
}

}  // namespace fleetgw::web
