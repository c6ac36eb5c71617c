#include "gateway/tools/store/ride_command.h"

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <limits>
#include <optional>
#include <vector>

#include "gateway/config/config.h"
#include "gateway/runtime/recorder.h"
#include "gateway/tools/common/table_format.h"
#include "gateway/tools/plot/ride_plot.h"
#include "gateway/tools/plot/ride_plot_map.h"
#include "gateway/tools/store/store_open.h"
#include "storage/store.h"

namespace fleetgw::tools {
namespace ride_cli {
namespace {

constexpr std::int64_t kMicros = 1'000'000;

// The ride `id` names, or the latest when no ride has that id and it is "latest".
std::optional<storage::RideRow> find_ride(storage::Store& store, const std::string& id) {
  if (auto ride = store.ride(id)) return ride;
  if (id != "latest") return std::nullopt;
  std::string newest;
  store.list_recent("rides", std::numeric_limits<std::int64_t>::min(), 1,
                    [&newest](const nlohmann::json& row) {
                      const auto it = row.find("ride_id");
                      if (it != row.end() && it->is_string()) newest = it->get<std::string>();
                    });
  if (newest.empty()) return std::nullopt;
  return store.ride(newest);
}

RidePlot plot_of(const storage::RideRow& ride, const std::vector<storage::TelemetryRow>& telemetry,
                 const motinova::DecodeOptions& protocol, std::ostream& err) {
  RidePlot plot;
  plot.ride_id = ride.ride_id;
  plot.start_us = ride.start_us;
  plot.open = ride.state == storage::RideState::kOpen || !ride.end_us;
  const bool odometer = ride.start_odo_km && ride.end_odo_km;
  plot.distance_km = odometer ? ride.distance_km : ride.distance_integrated_km;
  if (odometer) plot.odometer_km = ride.distance_km;
  plot.gnss_distance_m = ride.gnss_distance_m;
  plot.track = plot_track(ride.ride_id, ride.track, err);
  for (const auto& t : telemetry) {
    PlotSample s;
    s.t_s = static_cast<double>(t.ts_us - ride.start_us) / kMicros;
    s.speed_kmh = t.speed_kmh;
    if (t.voltage_v && t.current_a) s.power_w = *t.voltage_v * *t.current_a;
    s.soc_pct = t.soc_pct;
    s.assist_level = t.assist_level;
    plot.samples.push_back(s);
  }
  plot.duration_s =
      ride.end_us ? static_cast<double>(*ride.end_us - ride.start_us) / kMicros : ride.duration_s;
  if (!ride.end_us && !plot.samples.empty()) {
    plot.duration_s = std::max(plot.duration_s, plot.samples.back().t_s);
  }
  for (const auto& a : protocol.assist_names) plot.assist_names.emplace_back(a.value, a.name);
  plot.gap_s = gap_threshold_s(plot.samples);
  return plot;
}

}  // namespace
}  // namespace ride_cli

std::unique_ptr<RideCommand> add_ride_command(CLI::App& app) {
  auto ride = std::make_unique<RideCommand>();
  ride->command = app.add_subcommand("ride", "look at one ride from the SQLite store (read-only)");
  ride->command->require_subcommand(1);
  ride->plot = ride->command->add_subcommand(
      "plot",
      "speed, power, SOC and assist over the ride, and its GNSS track, as a self-contained SVG");
  ride->plot
      ->add_option("ride_id", ride->ride_id, "ride id as `fleetgw db rides` shows it, or latest")
      ->required();
  ride->plot->add_option("--out", ride->out_path, "SVG file to write (- for stdout)")->required();
  ride->config_option = ride->plot->add_option(
      "--config", ride->config_file, "configuration file (storage.path, assist-level names)");
  ride->plot->add_option("--db", ride->db_path, "database file (overrides the configuration)");
  return ride;
}

int run_ride_command(const RideCommand& ride, std::ostream& out, std::ostream& err) {
  storage::StoreOptions options;
  motinova::DecodeOptions protocol;
  if (ride.db_path.empty() || ride.config_option->count() > 0) {
    const config::Config cfg = config::load_config(ride.config_file);
    protocol = cfg.protocol;
    options = runtime::make_store_options(cfg);
  }
  if (!ride.db_path.empty()) options.path = ride.db_path;
  std::optional<storage::Store> store;
  if (const int rc = open_store_read_only(std::move(options), "ride plot", store, err); rc != 0) {
    return rc;
  }
  const auto found = ride_cli::find_ride(*store, ride.ride_id);
  if (!found) {
    err << "fleetgw ride plot: "
        << (ride.ride_id == "latest" ? "no rides" : "no ride '" + table_cell(ride.ride_id) + "'")
        << " in " << table_cell(store->path()) << " (fleetgw db rides lists them)\n";
    return 1;
  }
  const std::int64_t end_us = found->end_us.value_or(std::numeric_limits<std::int64_t>::max());
  const RidePlot plot =
      ride_cli::plot_of(*found, store->telemetry_between(found->start_us, end_us), protocol, err);
  const std::string svg = render_ride_svg(plot);
  if (ride.out_path == "-") {
    out << svg;
    return 0;
  }
  std::ofstream file(ride.out_path, std::ios::binary | std::ios::trunc);
  if (file) file << svg;
  if (file) file.close();
  if (!file) {
    err << "fleetgw ride plot: cannot write '" << table_cell(ride.out_path)
        << "': " << std::strerror(errno) << '\n';
    return 1;
  }
  out << ride.out_path << ": ride " << table_cell(found->ride_id) << ", " << plot.samples.size()
      << " samples over " << fmt::format("{:.1f}", plot.duration_s / 60.0) << " min\n";
  return 0;
}

}  // namespace fleetgw::tools
