// Ed25519 keys over OpenSSL's EVP API: verification for the gateway, signing and key generation
// for the operator tools and the tests.
//
// Contract:
//  * Value-like, move-only RAII wrappers (unique_ptr with EVP_PKEY_free); no global state.
//  * Public keys are the 32-byte raw encoding (RFC 8032), in the configuration as base64.
//    from_raw()/from_base64() return nullopt for anything that is not exactly such a key.
//  * verify() is pure Ed25519 (no pre-hash, no context) over exactly the given bytes; it never
//    throws and returns false for a signature of the wrong length or any OpenSSL error.
//  * Private keys are PKCS#8 PEM files. load_pem() throws std::runtime_error naming the file
//    (unreadable, not PEM, not an Ed25519 key); write_pem() creates the file with mode 0600 and
//    refuses to overwrite an existing one.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

struct evp_pkey_st;

namespace fleetgw::command {

inline constexpr std::size_t kEd25519PublicKeyBytes = 32;
inline constexpr std::size_t kEd25519SignatureBytes = 64;

struct EvpPkeyDeleter {
  void operator()(evp_pkey_st* key) const noexcept;
};
using EvpPkeyPtr = std::unique_ptr<evp_pkey_st, EvpPkeyDeleter>;

class Ed25519PublicKey {
 public:
  static std::optional<Ed25519PublicKey> from_raw(std::span<const std::uint8_t> raw);
  static std::optional<Ed25519PublicKey> from_base64(std::string_view text);

  bool verify(std::span<const std::uint8_t> message, std::span<const std::uint8_t> signature) const;
  const std::array<std::uint8_t, kEd25519PublicKeyBytes>& raw() const { return raw_; }
  std::string base64() const;

 private:
  Ed25519PublicKey(EvpPkeyPtr key, std::array<std::uint8_t, kEd25519PublicKeyBytes> raw)
      : key_(std::move(key)), raw_(raw) {}
  EvpPkeyPtr key_;
  std::array<std::uint8_t, kEd25519PublicKeyBytes> raw_{};
};

class Ed25519PrivateKey {
 public:
  // A fresh key from OpenSSL's CSPRNG. Throws std::runtime_error if OpenSSL fails.
  static Ed25519PrivateKey generate();
  static Ed25519PrivateKey load_pem(const std::filesystem::path& file);
  static Ed25519PrivateKey from_pem(std::string_view pem, std::string_view name = "<memory>");

  std::vector<std::uint8_t> sign(std::span<const std::uint8_t> message) const;
  Ed25519PublicKey public_key() const;
  std::string pem() const;
  void write_pem(const std::filesystem::path& file) const;

 private:
  explicit Ed25519PrivateKey(EvpPkeyPtr key) : key_(std::move(key)) {}
  EvpPkeyPtr key_;
};

// `size` random bytes from OpenSSL's CSPRNG (command ids). Throws std::runtime_error on failure.
std::vector<std::uint8_t> random_bytes(std::size_t size);

}  // namespace fleetgw::command
