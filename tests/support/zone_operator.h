// Test support: the operator's side of geofencing, through the shipped binary: a signing key
// made by `fleetgw keygen`, zones drawn as GeoJSON, bundles signed by `fleetgw zones sign`.
//
// Contract:
//  * geojson_rect() is a Polygon's "coordinates" value: one ring, the four [lon, lat] corners of
//    a rectangle, 9 significant digits. geojson_feature() is one Feature with properties id,
//    kind and `extra` (more JSON members as given, each starting with a comma).
//  * ZoneOperator(dir, binary) runs `<binary> keygen <dir>/ops` at once: the private key is
//    key_file() (<dir>/ops.pem), its id "ops"; key_line() is the `ops = "<public key>"` line
//    keygen prints, for a gateway's [command.trusted_keys]. std::runtime_error (with the tool's
//    output) when the tool fails or prints no such line.
//  * bundle_file() writes the features as <dir>/zones-<version>.geojson, signs them into
//    <dir>/zones-<version>.pb and returns that path; bundle() returns the signed bytes.
//    std::runtime_error (with the tool's output) when signing fails or writes no file.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "tests/support/temp_dir.h"

namespace fleetgw::testing {

std::string geojson_rect(double lon0, double lon1, double lat0, double lat1);
std::string geojson_feature(const std::string& id, const std::string& kind,
                            const std::string& coordinates, const std::string& extra = "");

class ZoneOperator {
 public:
  ZoneOperator(const TempDir& dir, std::filesystem::path binary);

  const std::string& key_line() const { return key_line_; }
  std::filesystem::path key_file() const { return dir_ / "ops.pem"; }
  std::filesystem::path bundle_file(int version, const std::vector<std::string>& features) const;
  std::string bundle(int version, const std::vector<std::string>& features) const;

 private:
  // `<binary> args...`; its output (std::runtime_error with that output when it fails).
  std::string run(const std::vector<std::string>& args) const;

  std::filesystem::path dir_;
  std::filesystem::path binary_;
  std::string key_line_;
};

}  // namespace fleetgw::testing
