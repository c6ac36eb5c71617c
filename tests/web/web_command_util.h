// Test support for the console's commands (issue 28): Ed25519 keys made by the openssl CLI (as
// a deployment would), signatures checked with OpenSSL, delegations signed by a test root, and
// a raw MQTT client that sees what `fleetgw serve` publishes and answers as a bike would.
//
// Contract:
//  * make_key() writes a PKCS#8 PEM Ed25519 private key with mode `mode`; public_key() is its
//    raw 32-byte public key, public_key_b64() that in base64 ([command.trusted_keys] form).
//  * sign_delegation() returns a serialized fleetgw.v1.SignedDelegation of `d` by `root_key`.
//  * TopicClient connects (clean session) and has subscribed `filter` at QoS 1 when the
//    constructor returns; messages() is a copy of what arrived (topic, payload).
//  * result_envelope() is an Envelope with a CommandResult answering `signed_payload` (a
//    SignedCommand) as an authentic command's result: its command_id and command_sha256.
#pragma once

#include <mqtt/async_client.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <sys/stat.h>

#include <atomic>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "fleetgw/v1/command.pb.h"
#include "fleetgw/v1/envelope.pb.h"
#include "fleetgw/v1/keys.pb.h"
#include "tests/support/process.h"

namespace fleetgw::testing {

inline void make_key(const std::filesystem::path& file, std::filesystem::perms mode) {
  run_program({"openssl", "genpkey", "-algorithm", "ed25519", "-out", file.string()},
              file.string() + ".log");
  std::filesystem::permissions(file, mode);
}

inline std::string public_key(const std::filesystem::path& file) {
  std::FILE* f = std::fopen(file.c_str(), "rb");
  if (f == nullptr) throw std::runtime_error("cannot open " + file.string());
  EVP_PKEY* k = PEM_read_PrivateKey(f, nullptr, nullptr, nullptr);
  std::fclose(f);
  if (k == nullptr) throw std::runtime_error("not a key: " + file.string());
  unsigned char pub[32];
  std::size_t len = sizeof pub;
  EVP_PKEY_get_raw_public_key(k, pub, &len);
  EVP_PKEY_free(k);
  return std::string(reinterpret_cast<char*>(pub), len);
}

inline std::string public_key_b64(const std::filesystem::path& file) {
  const std::string raw = public_key(file);
  unsigned char out[64];
  const int n = EVP_EncodeBlock(out, reinterpret_cast<const unsigned char*>(raw.data()),
                                static_cast<int>(raw.size()));
  return std::string(reinterpret_cast<char*>(out), static_cast<std::size_t>(n));
}

inline bool ed25519_verifies(const std::string& pub, const std::string& msg,
                             const std::string& sig) {
  EVP_PKEY* k = EVP_PKEY_new_raw_public_key(
      EVP_PKEY_ED25519, nullptr, reinterpret_cast<const unsigned char*>(pub.data()), pub.size());
  EVP_MD_CTX* ctx = EVP_MD_CTX_new();
  const bool ok =
      k != nullptr && ctx != nullptr &&
      EVP_DigestVerifyInit(ctx, nullptr, nullptr, nullptr, k) == 1 &&
      EVP_DigestVerify(ctx, reinterpret_cast<const unsigned char*>(sig.data()), sig.size(),
                       reinterpret_cast<const unsigned char*>(msg.data()), msg.size()) == 1;
  EVP_MD_CTX_free(ctx);
  EVP_PKEY_free(k);
  return ok;
}

inline std::string ed25519_sign(const std::filesystem::path& key_file, const std::string& msg) {
  std::FILE* f = std::fopen(key_file.c_str(), "rb");
  EVP_PKEY* k = f ? PEM_read_PrivateKey(f, nullptr, nullptr, nullptr) : nullptr;
  if (f) std::fclose(f);
  EVP_MD_CTX* ctx = EVP_MD_CTX_new();
  unsigned char sig[64];
  std::size_t len = sizeof sig;
  EVP_DigestSignInit(ctx, nullptr, nullptr, nullptr, k);
  EVP_DigestSign(ctx, sig, &len, reinterpret_cast<const unsigned char*>(msg.data()), msg.size());
  EVP_MD_CTX_free(ctx);
  EVP_PKEY_free(k);
  return std::string(reinterpret_cast<char*>(sig), len);
}

inline std::string sha256_raw(const std::string& data) {
  unsigned char md[32];
  unsigned int len = 0;
  EVP_Digest(data.data(), data.size(), md, &len, EVP_sha256(), nullptr);
  return std::string(reinterpret_cast<char*>(md), len);
}

inline std::string sign_delegation(const std::filesystem::path& root_key,
                                   const std::string& root_id, const v1::Delegation& d) {
  v1::SignedDelegation sd;
  sd.set_delegation(d.SerializeAsString());
  sd.set_signature(ed25519_sign(root_key, sd.delegation()));
  sd.set_root_key_id(root_id);
  return sd.SerializeAsString();
}

class TopicClient {
 public:
  TopicClient(const std::string& uri, const std::string& filter)
      : client_(uri, "web-test-" + std::to_string(::getpid()) + "-" + std::to_string(++count())) {
    client_.set_message_callback([this](mqtt::const_message_ptr m) {
      const std::lock_guard lock(mu_);
      messages_.emplace_back(m->get_topic(), m->get_payload());
    });
    mqtt::connect_options o;
    o.set_clean_session(true);
    client_.connect(o)->wait();
    client_.subscribe(filter, 1)->wait();
  }
  ~TopicClient() {
    try {
      client_.disconnect()->wait_for(std::chrono::seconds(2));
    } catch (const mqtt::exception&) {
    }
  }
  std::vector<std::pair<std::string, std::string>> messages() {
    const std::lock_guard lock(mu_);
    return messages_;
  }
  void publish(const std::string& topic, const std::string& payload) {
    client_.publish(topic, payload.data(), payload.size(), 1, false)->wait();
  }

 private:
  static int& count() {
    static int n = 0;  // per process: unique client ids
    return n;
  }
  mqtt::async_client client_;
  std::mutex mu_;
  std::vector<std::pair<std::string, std::string>> messages_;
};

inline std::string result_envelope(const std::string& vehicle, const std::string& signed_payload,
                                   v1::CommandResultCode code, const std::string& reason,
                                   bool bind = true) {
  v1::SignedCommand sc;
  sc.ParseFromString(signed_payload);
  v1::Command c;
  c.ParseFromString(sc.command());
  v1::Envelope env;
  env.set_vehicle_id(vehicle);
  auto* r = env.mutable_command_result();
  r->set_command_id(c.command_id());
  r->set_result(code);
  r->set_reason(reason);
  r->set_operator_id(c.operator_id());
  if (bind) r->set_command_sha256(sha256_raw(sc.command()));
  return env.SerializeAsString();
}

}  // namespace fleetgw::testing
