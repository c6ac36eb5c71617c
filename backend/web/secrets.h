// Passwords, tokens and their hashes, over libsodium.
//
// Contract:
//  * hash_password() returns an Argon2id string (libsodium's crypto_pwhash_str, "$argon2id$..."
//    with its salt and cost inside: 2 passes over 64 MiB, libsodium's "interactive" limits);
//    verify_password() checks one, false for a wrong password or a malformed hash. Both throw
//    std::runtime_error only when the memory cannot be had.
//  * random_token() is `bytes` random bytes from the kernel's generator, base64url without
//    padding (cookie- and header-safe). sha256_hex() is what the database stores of a token.
//  * same_secret() compares in constant time for equal lengths.
//  * Every function may be called from any thread (libsodium is initialised once, thread-safely).
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace fleetgw::web {

std::string hash_password(std::string_view password);
bool verify_password(std::string_view hash, std::string_view password);
std::string random_token(std::size_t bytes = 32);
std::string sha256_hex(std::string_view data);
bool same_secret(std::string_view a, std::string_view b);

}  // namespace fleetgw::web
