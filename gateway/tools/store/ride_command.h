// `fleetgw ride plot RIDE_ID --out FILE`: a picture of one ride
// (gateway/tools/plot/ride_plot.h) from the SQLite store.
//
// Contract:
//  * The store is opened read-only as `fleetgw db` opens it (db_command.h): `--db PATH`, else
//    storage.path of `--config FILE` (default /etc/fleetgw/fleetgw.toml). A path that is not a
//    fleetgw store exits 2 naming it.
//  * RIDE_ID is a ride id as `fleetgw db rides` shows it, or `latest` (the ride that started
//    last) when no ride has that id. No such ride: exit 1 with a message naming the id (made
//    printable) and the store.
//  * The plot covers the ride row's window [start, end] (an open ride: up to its last sample)
//    and the telemetry samples in it: speed, power = voltage x current (discharge positive),
//    SOC and assist level, whose names come from [protocol] of the configuration when one is
//    read (--config given, or no --db), else the built-in U7 names. Gaps: gap_threshold_s().
//    Distance as in `db rides`: the odometer distance when the ride has odometer readings,
//    else the integrated one.
//  * The ride row's GNSS track (`rides.track`, schema v6) becomes the map panel
//    (ride_plot_map.h), captioned with its GNSS distance and the odometer distance; a stored
//    track that is not valid is left out with one warning on `err` naming the ride, and the
//    plot is still written (exit 0).
//  * `--out -` writes the SVG to `out`; otherwise the file is written (replaced) and one line
//    on `out` says what was written. A file that cannot be written exits 1.
//  * Usage errors (no RIDE_ID, no --out) are CLI11's: exit 2 in run_cli.
#pragma once

#include <memory>
#include <ostream>
#include <string>

namespace CLI {
class App;
class Option;
}  // namespace CLI

namespace fleetgw::tools {

struct RideCommand {
  CLI::App* command = nullptr;
  CLI::App* plot = nullptr;
  CLI::Option* config_option = nullptr;
  std::string ride_id;
  std::string out_path;
  std::string config_file = "/etc/fleetgw/fleetgw.toml";
  std::string db_path;  // overrides storage.path of the configuration
};

// Registers `ride` and `ride plot` on `app`; the returned object receives the values.
std::unique_ptr<RideCommand> add_ride_command(CLI::App& app);
int run_ride_command(const RideCommand& ride, std::ostream& out, std::ostream& err);

}  // namespace fleetgw::tools
