// Options and one-off administration of the registry and the public feeds
// (registry_options.h).
#include "backend/web/registry_options.h"

#include <CLI/CLI.hpp>

#include <cctype>
#include <fstream>
#include <iostream>
#include <sstream>

#include "backend/common/pg.h"
#include "backend/web/auth.h"
#include "backend/web/console_schema.h"
#include "backend/web/registry_store.h"

namespace fleetgw::web {
namespace {

std::string read_admin_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::invalid_argument(path + ": cannot be read");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

void add_standards_options(CLI::App& app, StandardsOptions& o) {
  app.add_option("--public-url", o.public_url,
                 "absolute base URL of the GBFS/MDS links (default: the request's Host)");
  app.add_option("--gbfs-system-id", o.system_id, "GBFS system_id")->capture_default_str();
  app.add_option("--gbfs-name", o.system_name, "GBFS system name")->capture_default_str();
  app.add_option("--gbfs-language", o.language, "GBFS language (BCP 47)")->capture_default_str();
  app.add_option("--gbfs-timezone", o.timezone, "GBFS timezone (IANA)")->capture_default_str();
  app.add_option("--gbfs-email", o.contact_email, "GBFS feed_contact_email")->capture_default_str();
  app.add_option("--gbfs-opening-hours", o.opening_hours, "GBFS opening_hours (OSM syntax)")
      ->capture_default_str();
  app.add_option("--provider-id", o.provider_id,
                 "MDS provider_id (UUID) of registry entries that give none");
  app.add_option("--provider-name", o.provider_name, "MDS provider name")->capture_default_str();
  app.add_option("--low-battery-pct", o.low_battery_pct,
                 "below this SOC a vehicle is disabled (GBFS) / battery_low (MDS)")
      ->check(CLI::Range(1, 99))
      ->capture_default_str();
  app.add_option("--charged-pct", o.charged_pct, "SOC that ends battery_low (MDS battery_charged)")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_option("--offline-after-s", o.offline_after_s,
                 "a vehicle silent longer is disabled (GBFS) / comms_lost (MDS)")
      ->check(CLI::Range(10, 86400))
      ->capture_default_str();
  app.add_option("--mds-page-size", o.mds_page_size, "rows (or vehicles) per MDS page")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--register-vehicle", o.register_vehicle,
                 "register vehicle ID (with --vehicle-type, optional --device-uuid) and exit");
  app.add_option("--vehicle-type", o.vehicle_type, "vehicle type of --register-vehicle");
  app.add_option("--device-uuid", o.device_uuid, "device UUID of --register-vehicle");
  app.add_option("--import-vehicle-types", o.import_vehicle_types,
                 "register the vehicle types of a CSV file and exit");
  app.add_option("--import-registry", o.import_registry,
                 "register the vehicles of a CSV file and exit");
  app.add_option("--add-mds-agency", o.add_mds_agency,
                 "create an MDS agency NAME, print its bearer token (once) and exit");
  app.add_option("--import-zone-bundle", o.import_zone_bundle,
                 "store a signed zone bundle (fleetgw zones sign) as published, and exit");
  for (const char* name :
       {"public-url", "gbfs-system-id", "gbfs-name", "gbfs-language", "gbfs-timezone", "gbfs-email",
        "gbfs-opening-hours", "provider-id", "provider-name", "low-battery-pct", "charged-pct",
        "offline-after-s", "mds-page-size"}) {
    std::string env = "FLEETGW_SERVE_";
    for (const char* c = name; *c != '\0'; ++c) {
      env += *c == '-' ? '_' : static_cast<char>(std::toupper(static_cast<unsigned char>(*c)));
    }
    app.get_option(std::string("--") + name)->envname(env);
  }
}

int run_standards_admin(const std::string& pg, const StandardsOptions& o) {
  // Two connections: the work's, and the audit's (Auth leases its own).
  PgPool pool(pg, 2);
  auto c = pool.lease();
  migrate_console_schema(*c);
  Auth auth(pool);
  try {
    if (!o.import_vehicle_types.empty()) {
      const auto types =
          parse_vehicle_types_csv(read_admin_file(o.import_vehicle_types), o.import_vehicle_types);
      PgTransaction tx(*c);
      for (const VehicleType& t : types) upsert_vehicle_type(*c, t, now_us());
      tx.commit();
      std::cout << types.size() << " vehicle type(s) saved\n";
    }
    if (!o.import_registry.empty()) {
      auto vehicles = parse_registry_csv(read_admin_file(o.import_registry), o.import_registry);
      for (RegistryVehicle& v : vehicles) {
        if (v.provider_id.empty()) v.provider_id = o.provider_id;
        if (v.provider_name.empty()) v.provider_name = o.provider_name;
        try {
          upsert_vehicle(*c, v, now_us());
        } catch (const std::invalid_argument& e) {
          throw std::invalid_argument(o.import_registry + ": vehicle " + v.vehicle_id + ": " +
                                      e.what());
        }
      }
      std::cout << vehicles.size() << " vehicle(s) saved\n";
    }
    if (!o.register_vehicle.empty()) {
      if (o.vehicle_type.empty())
        throw std::invalid_argument("--register-vehicle needs --vehicle-type");
      RegistryVehicle v{o.register_vehicle, o.vehicle_type,  o.device_uuid,
                        o.provider_id,      o.provider_name, false};
      const std::string device = upsert_vehicle(*c, v, now_us());
      auth.audit(std::nullopt, "local", "registry_vehicle", v.vehicle_id, "ok", device);
      std::cout << "vehicle " << v.vehicle_id << " registered, device " << device << '\n';
    }
    if (!o.add_mds_agency.empty()) {
      const std::string token = add_mds_agency(*c, o.add_mds_agency, now_us());
      auth.audit(std::nullopt, "local", "mds_agency_add", o.add_mds_agency, "ok");
      std::cout << token << '\n';
    }
    if (!o.import_zone_bundle.empty()) {
      const std::uint64_t version =
          import_zone_bundle(*c, read_admin_file(o.import_zone_bundle), "local", now_us());
      auth.audit(std::nullopt, "local", "zone_bundle_import", std::to_string(version), "ok");
      std::cout << "zone bundle version " << version << " stored\n";
    }
  } catch (const std::invalid_argument& e) {
    std::cerr << "fleetgw serve: " << e.what() << '\n';
    return 2;
  } catch (const PgError& e) {
    std::cerr << "fleetgw serve: database: " << e.what() << '\n';
    return 1;
  }
  return 0;
}

}  // namespace fleetgw::web
