// Strict standard base64 (RFC 4648 §4, with padding) for key material in the configuration.
//
// Contract: pure functions. decode_base64() accepts only the canonical encoding: the standard
// alphabet, length a multiple of 4, '=' only as trailing padding, zero unused bits; surrounding
// ASCII whitespace is ignored. Anything else is nullopt, so a mangled key never turns into a
// different valid key.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace fleetgw::command {

std::string encode_base64(std::span<const std::uint8_t> bytes);
std::optional<std::vector<std::uint8_t>> decode_base64(std::string_view text);

}  // namespace fleetgw::command
