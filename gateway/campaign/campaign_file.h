// A campaign as an engineer writes it: a TOML or JSON file (docs/campaigns.md "The file") turned
// into a fleetgw.v1.Campaign. Syntax only; the rules are compile_campaign()'s.
//
// Contract: the text is TOML unless its first non-blank character is '{' (JSON). Every key is
// known (an unknown one is refused, naming it: a typo never silently drops a rule); each value
// has its type (a string where a number belongs is refused naming the key). start/end are
// RFC 3339 UTC ("2026-12-01T00:00:00Z", a TOML date-time too) or start_us/end_us integers;
// trigger day_start/day_end "HH:MM" or day_start_s/day_end_s. issued_at_us is left 0 (the
// signer sets it). Errors: std::nullopt-free -- a variant holding "<where>: <what>".
#pragma once

#include <string>
#include <string_view>
#include <variant>

namespace fleetgw::v1 {
class Campaign;
}  // namespace fleetgw::v1

namespace fleetgw::campaign {

std::variant<v1::Campaign, std::string> parse_campaign_text(std::string_view text,
                                                            std::string_view source_name);

}  // namespace fleetgw::campaign
