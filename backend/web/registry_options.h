// Options of `fleetgw serve` for the public feeds (GBFS, MDS) and the vehicle registry, and its
// one-off registry administration (like --add-operator: it runs, prints, and exits).
//
// Contract:
//  * add_standards_options() adds the options to the serve command line (with
//    FLEETGW_SERVE_<OPTION> environment fallbacks for the serving ones).
//  * admin_requested() is true when one of the administration options was given;
//    run_standards_admin() then migrates the console schema, does it and returns the exit code
//    (0 ok, 1 failure, 2 bad input, with a message naming what and where on stderr).
//      --register-vehicle ID --vehicle-type T [--device-uuid U]   (provider: --provider-id)
//      --import-vehicle-types FILE.csv   (registry_store.h: columns)
//      --import-registry FILE.csv
//      --add-mds-agency NAME             (prints the agency's bearer token, once)
//      --import-zone-bundle FILE         (a SignedZoneBundle as `fleetgw zones sign` writes it)
#pragma once

#include <string>

namespace CLI {
class App;
}

namespace fleetgw::web {

struct StandardsOptions {
  // Absolute base URL the feeds are reached at (e.g. https://fleet.example.org); empty: the
  // request's own scheme and Host header.
  std::string public_url;
  std::string system_id = "fleetgw";
  std::string system_name = "fleetgw bike share";
  std::string language = "en";
  std::string timezone = "Etc/UTC";
  std::string contact_email = "operator@example.org";
  std::string opening_hours = "24/7";
  // MDS provider_id (UUID) and name, the default of registry entries that give none.
  std::string provider_id;
  std::string provider_name = "fleetgw";
  int low_battery_pct = 20;   // below: GBFS is_disabled, MDS battery_low
  int charged_pct = 30;       // at or above after battery_low: MDS battery_charged
  int offline_after_s = 600;  // no report for longer: disabled / comms lost
  int mds_page_size = 1000;   // rows per MDS page (links.next)

  // One-off administration:
  std::string register_vehicle;
  std::string vehicle_type;
  std::string device_uuid;
  std::string import_vehicle_types;
  std::string import_registry;
  std::string add_mds_agency;
  std::string import_zone_bundle;

  bool admin_requested() const {
    return !register_vehicle.empty() || !import_vehicle_types.empty() || !import_registry.empty() ||
           !add_mds_agency.empty() || !import_zone_bundle.empty();
  }
};

void add_standards_options(CLI::App& app, StandardsOptions& o);
int run_standards_admin(const std::string& pg, const StandardsOptions& o);

}  // namespace fleetgw::web
