#include "gateway/command/signing.h"

#include <charconv>
#include <fstream>
#include <iostream>
#include <stdexcept>

#include "fleetgw/v1/command.pb.h"
#include "gateway/command/sha256.h"

namespace fleetgw::command {

bool is_valid_tool_id(std::string_view id) {
  if (id.empty() || id.size() > 64) return false;
  for (const char c : id) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '.' || c == '_' || c == '-';
    if (!ok) return false;
  }
  return true;
}

std::string random_command_id() {
  const auto bytes = random_bytes(16);
  return to_hex({reinterpret_cast<const char*>(bytes.data()), bytes.size()});
}

std::optional<v1::Command> make_command(std::string_view vehicle, std::string_view lock,
                                        std::string_view action, Micros issued_at,
                                        Micros expires_at, std::string command_id) {
  v1::Command c;
  if (action == "lock") {
    c.set_action(v1::COMMAND_ACTION_LOCK);
  } else if (action == "unlock") {
    c.set_action(v1::COMMAND_ACTION_UNLOCK);
  } else {
    return std::nullopt;
  }
  if (lock.empty()) return std::nullopt;
  if (lock == "vehicle") {
    c.set_whole_vehicle(true);
  } else {
    c.set_lock_kind(std::string(lock));
  }
  c.set_command_id(std::move(command_id));
  c.set_vehicle_id(std::string(vehicle));
  c.set_issued_at_us(issued_at.count());
  c.set_expires_at_us(expires_at.count());
  return c;
}

std::optional<v1::Command> make_mc_command(std::string_view vehicle, std::string_view action,
                                           std::string_view value, Micros issued_at,
                                           Micros expires_at, std::string command_id) {
  v1::Command c;
  if (action == "speed_limit") {
    unsigned kmh = 0;
    const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), kmh);
    // 0 is not a limit (and would travel as "no value": the gateway refuses both).
    if (ec != std::errc() || end != value.data() + value.size() || kmh == 0 || kmh > 255) {
      return std::nullopt;
    }
    c.mutable_speed_limit()->set_kmh(kmh);
  } else if (action == "assist_level") {
    if (value.empty()) return std::nullopt;
    c.mutable_assist_level()->set_level(std::string(value));
  } else if (action == "headlight") {
    if (value != "on" && value != "off") return std::nullopt;
    c.mutable_headlight()->set_on(value == "on");
  } else if (action == "clear_trip") {
    c.mutable_clear_trip();
  } else if (action == "power_off") {
    c.mutable_power_off();
  } else {
    return std::nullopt;
  }
  c.set_command_id(std::move(command_id));
  c.set_vehicle_id(std::string(vehicle));
  c.set_issued_at_us(issued_at.count());
  c.set_expires_at_us(expires_at.count());
  return c;
}

std::string sign_command(const v1::Command& command, const Ed25519PrivateKey& key,
                         std::string_view key_id, std::string* command_sha256) {
  v1::SignedCommand s;
  // Serialized once: the signature covers exactly the bytes that travel.
  s.set_command(command.SerializeAsString());
  const auto* bytes = reinterpret_cast<const std::uint8_t*>(s.command().data());
  const auto sig = key.sign({bytes, s.command().size()});
  s.set_signature(std::string(sig.begin(), sig.end()));
  s.set_key_id(std::string(key_id));
  if (command_sha256 != nullptr) *command_sha256 = sha256(s.command());
  return s.SerializeAsString();
}

int run_keygen(const std::filesystem::path& path_prefix, std::ostream& out, std::ostream& err,
               std::string_view key_id) {
  try {
    std::string id(key_id);
    if (id.empty()) id = path_prefix.filename().string();
    if (!is_valid_tool_id(id)) {
      err << "keygen: key id '" << id << "' must be 1..64 characters of [A-Za-z0-9._-]\n";
      return 1;
    }
    const auto key = Ed25519PrivateKey::generate();
    const std::filesystem::path pem = path_prefix.string() + ".pem";
    const std::filesystem::path pub = path_prefix.string() + ".pub";
    if (std::filesystem::exists(pub)) {
      err << "keygen: " << pub.string() << " exists; not overwritten\n";
      return 1;
    }
    key.write_pem(pem);
    const std::string pub64 = key.public_key().base64();
    std::ofstream(pub) << pub64 << '\n';
    err << "keygen: private key " << pem.string() << " (mode 0600), public key " << pub.string()
        << "\nkeygen: add this line to [command.trusted_keys] of the gateways' config:\n";
    out << id << " = \"" << pub64 << "\"\n";
    return 0;
  } catch (const std::exception& e) {
    err << "keygen: " << e.what() << '\n';
    return 1;
  }
}

int run_keygen(const std::filesystem::path& path_prefix, std::ostream& out) {
  return run_keygen(path_prefix, out, std::cerr);
}

SentCommand sign_for_sending(const v1::Command& command, const Ed25519PrivateKey& key,
                             std::string_view key_id) {
  SentCommand sent;
  sent.payload = sign_command(command, key, key_id, &sent.command_sha256);
  return sent;
}

SentCommand sign_for_sending(const v1::Command& command, const Ed25519PrivateKey& key,
                             std::string_view key_id, std::string_view signed_delegation) {
  SentCommand sent = sign_for_sending(command, key, key_id);
  if (signed_delegation.empty()) return sent;
  v1::SignedCommand s;
  s.ParseFromString(sent.payload);
  // Outside the signed bytes: the delegation carries the root's own signature.
  if (!s.mutable_delegation()->ParseFromString(std::string(signed_delegation))) {
    throw std::invalid_argument("not a fleetgw.v1.SignedDelegation");
  }
  sent.payload = s.SerializeAsString();
  return sent;
}

bool result_answers(const v1::CommandResult& result, std::string_view command_id,
                    const SentCommand& sent) {
  if (result.command_id() != command_id) return false;
  if (!result.command_sha256().empty()) return result.command_sha256() == sent.command_sha256;
  return !result.payload_sha256().empty() && result.payload_sha256() == sha256(sent.payload);
}

}  // namespace fleetgw::command
