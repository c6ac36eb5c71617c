// The zone bundle in force, kept in a file so it survives restarts and the bike enforces its
// zones offline from the start (issue 14). The only I/O of gateway/geofence/.
//
// Contract:
//  * The file holds the SignedZoneBundle exactly as received (signature included): at start-up
//    it is offered to the ZoneAuthority like any other payload, so a file altered on disk, or
//    signed by a key no longer trusted, is refused and not enforced.
//  * write_zone_file() is atomic: the bytes go to a temporary file in the same directory
//    (created exclusively, mode 0644), which is fsync'ed and renamed over the target, then the
//    directory is fsync'ed. A crash leaves either the old bundle or the new one, never a mix.
//  * Errors are return values with a message naming the path and the system error; nothing
//    throws. read_zone_file() returns nullopt with an empty `error` when the file does not
//    exist (no bundle received yet), and refuses a file over `max_bytes`.
//  * restore_zones() = read + offer; nullopt when there is no file or it could not be read
//    (`error` says which).
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include "gateway/geofence/zone_bundle.h"

namespace fleetgw::geofence {

std::optional<std::string> read_zone_file(const std::filesystem::path& path, std::string& error,
                                          std::size_t max_bytes = BundleLimits{}.max_payload_bytes);
bool write_zone_file(const std::filesystem::path& path, std::string_view payload,
                     std::string& error);
std::optional<BundleVerdict> restore_zones(ZoneAuthority& authority,
                                           const std::filesystem::path& path, std::string& error);

}  // namespace fleetgw::geofence
