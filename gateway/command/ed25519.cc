#include "gateway/command/ed25519.h"

#include <fcntl.h>
#include <openssl/bio.h>
#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/rand.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "gateway/command/base64.h"

namespace fleetgw::command {
namespace {

struct MdCtxDeleter {
  void operator()(EVP_MD_CTX* ctx) const noexcept { EVP_MD_CTX_free(ctx); }
};
using MdCtxPtr = std::unique_ptr<EVP_MD_CTX, MdCtxDeleter>;
struct PkeyCtxDeleter {
  void operator()(EVP_PKEY_CTX* ctx) const noexcept { EVP_PKEY_CTX_free(ctx); }
};
using PkeyCtxPtr = std::unique_ptr<EVP_PKEY_CTX, PkeyCtxDeleter>;
struct BioDeleter {
  void operator()(BIO* bio) const noexcept { BIO_free(bio); }
};
using BioPtr = std::unique_ptr<BIO, BioDeleter>;

std::string openssl_error() {
  const unsigned long e = ERR_get_error();
  ERR_clear_error();
  if (e == 0) return "unknown OpenSSL error";
  std::array<char, 256> buf{};
  ERR_error_string_n(e, buf.data(), buf.size());
  return buf.data();
}

}  // namespace

void EvpPkeyDeleter::operator()(evp_pkey_st* key) const noexcept {
  EVP_PKEY_free(key);
}

std::optional<Ed25519PublicKey> Ed25519PublicKey::from_raw(std::span<const std::uint8_t> raw) {
  if (raw.size() != kEd25519PublicKeyBytes) return std::nullopt;
  EvpPkeyPtr key(EVP_PKEY_new_raw_public_key(EVP_PKEY_ED25519, nullptr, raw.data(), raw.size()));
  if (!key) {
    ERR_clear_error();
    return std::nullopt;
  }
  std::array<std::uint8_t, kEd25519PublicKeyBytes> copy{};
  std::memcpy(copy.data(), raw.data(), copy.size());
  return Ed25519PublicKey(std::move(key), copy);
}

std::optional<Ed25519PublicKey> Ed25519PublicKey::from_base64(std::string_view text) {
  const auto raw = decode_base64(text);
  if (!raw) return std::nullopt;
  return from_raw(*raw);
}

bool Ed25519PublicKey::verify(std::span<const std::uint8_t> message,
                              std::span<const std::uint8_t> signature) const {
  if (!key_ || signature.size() != kEd25519SignatureBytes) return false;
  MdCtxPtr ctx(EVP_MD_CTX_new());
  if (!ctx) return false;
  // Ed25519 is a one-shot scheme: no digest (NULL) and a single EVP_DigestVerify call.
  if (EVP_DigestVerifyInit(ctx.get(), nullptr, nullptr, nullptr, key_.get()) != 1) {
    ERR_clear_error();
    return false;
  }
  const int rc = EVP_DigestVerify(ctx.get(), signature.data(), signature.size(), message.data(),
                                  message.size());
  if (rc != 1) ERR_clear_error();
  return rc == 1;
}

std::string Ed25519PublicKey::base64() const {
  return encode_base64(raw_);
}

Ed25519PrivateKey Ed25519PrivateKey::generate() {
  PkeyCtxPtr ctx(EVP_PKEY_CTX_new_id(EVP_PKEY_ED25519, nullptr));
  EVP_PKEY* raw = nullptr;
  if (!ctx || EVP_PKEY_keygen_init(ctx.get()) != 1 || EVP_PKEY_keygen(ctx.get(), &raw) != 1) {
    throw std::runtime_error("Ed25519 key generation failed: " + openssl_error());
  }
  return Ed25519PrivateKey(EvpPkeyPtr(raw));
}

Ed25519PrivateKey Ed25519PrivateKey::from_pem(std::string_view pem, std::string_view name) {
  BioPtr bio(BIO_new_mem_buf(pem.data(), static_cast<int>(pem.size())));
  if (!bio) throw std::runtime_error(std::string(name) + ": " + openssl_error());
  EvpPkeyPtr key(PEM_read_bio_PrivateKey(bio.get(), nullptr, nullptr, nullptr));
  if (!key) {
    throw std::runtime_error(std::string(name) + ": not a PEM private key (" + openssl_error() +
                             ")");
  }
  if (EVP_PKEY_id(key.get()) != EVP_PKEY_ED25519) {
    throw std::runtime_error(std::string(name) + ": not an Ed25519 key");
  }
  return Ed25519PrivateKey(std::move(key));
}

Ed25519PrivateKey Ed25519PrivateKey::load_pem(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error(file.string() + ": cannot read the key file");
  std::ostringstream text;
  text << in.rdbuf();
  return from_pem(text.str(), file.string());
}

std::vector<std::uint8_t> Ed25519PrivateKey::sign(std::span<const std::uint8_t> message) const {
  MdCtxPtr ctx(EVP_MD_CTX_new());
  std::size_t len = kEd25519SignatureBytes;
  std::vector<std::uint8_t> sig(len);
  if (!ctx || EVP_DigestSignInit(ctx.get(), nullptr, nullptr, nullptr, key_.get()) != 1 ||
      EVP_DigestSign(ctx.get(), sig.data(), &len, message.data(), message.size()) != 1) {
    throw std::runtime_error("Ed25519 signing failed: " + openssl_error());
  }
  sig.resize(len);
  return sig;
}

Ed25519PublicKey Ed25519PrivateKey::public_key() const {
  std::array<std::uint8_t, kEd25519PublicKeyBytes> raw{};
  std::size_t len = raw.size();
  if (EVP_PKEY_get_raw_public_key(key_.get(), raw.data(), &len) != 1 || len != raw.size()) {
    throw std::runtime_error("Ed25519 public key extraction failed: " + openssl_error());
  }
  auto pub = Ed25519PublicKey::from_raw(raw);
  if (!pub) throw std::runtime_error("Ed25519 public key rejected by OpenSSL");
  return std::move(*pub);
}

std::string Ed25519PrivateKey::pem() const {
  BioPtr bio(BIO_new(BIO_s_mem()));
  if (!bio ||
      PEM_write_bio_PrivateKey(bio.get(), key_.get(), nullptr, nullptr, 0, nullptr, nullptr) != 1) {
    throw std::runtime_error("PEM encoding failed: " + openssl_error());
  }
  char* data = nullptr;
  const long len = BIO_get_mem_data(bio.get(), &data);
  return std::string(data, static_cast<std::size_t>(len));
}

void Ed25519PrivateKey::write_pem(const std::filesystem::path& file) const {
  const std::string text = pem();
  // O_EXCL: never replace an existing key (it may be the one the fleet trusts); 0600 from the
  // start, so the key is never readable by others even for an instant.
  const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) {
    throw std::runtime_error(file.string() +
                             ": cannot create the key file: " + std::strerror(errno));
  }
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = errno;
      ::close(fd);
      ::unlink(file.c_str());
      throw std::runtime_error(file.string() + ": write failed: " + std::strerror(err));
    }
    done += static_cast<std::size_t>(n);
  }
  const bool synced = ::fsync(fd) == 0;
  const int sync_err = errno;
  if (::close(fd) != 0 || !synced) {
    throw std::runtime_error(file.string() +
                             ": write failed: " + std::strerror(synced ? errno : sync_err));
  }
}

std::vector<std::uint8_t> random_bytes(std::size_t size) {
  std::vector<std::uint8_t> out(size);
  if (size > 0 && RAND_bytes(out.data(), static_cast<int>(size)) != 1) {
    throw std::runtime_error("random bytes: " + openssl_error());
  }
  return out;
}

}  // namespace fleetgw::command
