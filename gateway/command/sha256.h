// SHA-256 (OpenSSL EVP) of a byte string: what binds a CommandResult to the exact signed
// Command bytes it answers (CommandResult.command_sha256).
//
// Contract: sha256(bytes) returns the 32-byte raw digest; it never fails for valid input
// (OpenSSL errors, which only a broken library could cause, throw std::runtime_error).
// to_hex() is the lowercase hex form for logs and JSON.
#pragma once

#include <string>
#include <string_view>

namespace fleetgw::command {

std::string sha256(std::string_view bytes);
std::string to_hex(std::string_view bytes);

}  // namespace fleetgw::command
