#include "gateway/tools/store/db_command.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <limits>

#include "gateway/config/config.h"
#include "gateway/runtime/recorder.h"
#include "gateway/tools/common/table_format.h"
#include "gateway/tools/common/time_arg.h"
#include "gateway/tools/store/db_geojson.h"
#include "gateway/tools/store/db_listings.h"
#include "gateway/tools/store/db_summary.h"
#include "gateway/tools/store/store_open.h"
#include "storage/store.h"

namespace fleetgw::tools {
namespace {

constexpr std::pair<const char*, const char*> kListings[] = {
    {"rides", "rides, newest first (start, duration, distance, speed, energy, SOC)"},
    {"faults", "fault events, newest first (node, fault, severity, raised/cleared)"},
    {"commands", "remote commands, newest first (result, reason, final lock state)"},
    {"alarms", "operator alarms, newest first (theft, tamper, battery)"},
};

void add_since(CLI::App& c, DbCommand& db) {
  c.add_option("--since", db.since,
               "only rows at or after this time: 2026-11-27T10:00:00Z, 2026-11-27, 90s, 15m, "
               "2h, 3d, or microseconds since the epoch");
}

void add_format(CLI::App& c, DbCommand& db, const char* what) {
  c.add_option("--format", db.format, what)->check(CLI::IsMember({"table", "json", "csv"}));
}

// `db export --format csv`: streamed, so a table of days of telemetry is never held in memory.
std::uint64_t export_csv(storage::Store& store, const std::string& table, std::int64_t since_us,
                         std::ostream& out) {
  std::vector<Column> columns;
  for (auto& name : store.export_columns(table)) {
    columns.push_back({name, name, -1});  // -1: full precision, the value parses back exactly
  }
  write_csv_header(columns, out);
  std::vector<nlohmann::json> cells(columns.size());
  return store.export_table(table, since_us, [&](const nlohmann::json& row) {
    for (std::size_t c = 0; c < columns.size(); ++c) {
      const auto it = row.find(columns[c].key);
      cells[c] = it == row.end() ? nlohmann::json() : *it;
    }
    write_csv_record(columns, cells, out);
  });
}

int run_summary(storage::Store& store, const DbCommand& db, std::optional<std::int64_t> since_us,
                std::ostream& out) {
  SummaryRows rows;
  const std::int64_t from = since_us.value_or(std::numeric_limits<std::int64_t>::min());
  const std::pair<const char*, std::vector<nlohmann::json>*> listings[] = {
      {"rides", &rows.rides},
      {"faults", &rows.faults},
      {"commands", &rows.commands},
      {"alarms", &rows.alarms}};
  for (const auto& listing : listings) {
    // (A lambda cannot capture a structured binding before C++20 as clang 14 implements it.)
    auto* into = listing.second;
    store.list_recent(listing.first, from, 0,
                      [into](const nlohmann::json& row) { into->push_back(row); });
  }
  const DbSummary summary = summarize(rows, since_us);
  switch (parse_output_format(db.format).value_or(OutputFormat::kTable)) {
    case OutputFormat::kTable:
      out << summary_sentence(summary) << "\n\n";
      write_table(summary_table(summary), out);
      break;
    case OutputFormat::kJson:
      out << summary_json(summary).dump(2, ' ', false, nlohmann::json::error_handler_t::replace)
          << '\n';
      break;
    case OutputFormat::kCsv:
      write_csv(flatten(summary_json(summary)), out);
      break;
  }
  return 0;
}

}  // namespace

std::unique_ptr<DbCommand> add_db_command(CLI::App& app) {
  auto db = std::make_unique<DbCommand>();
  db->command = app.add_subcommand("db", "inspect the SQLite store, read-only (technicians)");
  db->command->require_subcommand(1);
  db->stats = db->command->add_subcommand("stats", "row counts, outbox depth, size, evictions");
  db->export_rows = db->command->add_subcommand(
      "export",
      "one table, every row: JSON lines (default), CSV (--format csv), or for rides GeoJSON "
      "(--format geojson)");
  db->summary = db->command->add_subcommand(
      "summary", "what happened, in one sentence: rides, faults, commands, alarms");
  std::vector<CLI::App*> all = {db->stats, db->export_rows, db->summary};
  for (const auto& [name, help] : kListings) {
    auto* c = db->command->add_subcommand(name, help);
    db->listings.emplace_back(name, c);
    all.push_back(c);
    add_since(*c, *db);
    add_format(*c, *db, "output format (default: table)");
    c->add_option("--limit", db->limit, "at most this many rows, newest first (0: all)")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
  }
  for (auto* c : all) {
    c->add_option("--config", db->config_file, "configuration file (for storage.path)");
    c->add_option("--db", db->db_path, "database file (overrides the configuration)");
  }
  add_format(*db->stats, *db, "output format (default: table on a terminal, else json)");
  db->export_rows->add_option("--table", db->table, "table to export")->required();
  db->export_rows
      ->add_option("--format", db->export_format,
                   "jsonl: one JSON object per line (default); csv: RFC 4180 with a header; "
                   "geojson: a FeatureCollection, one Feature per ride with its track (rides)")
      ->check(CLI::IsMember({"jsonl", "csv", "geojson"}));
  add_since(*db->export_rows, *db);
  add_since(*db->summary, *db);
  add_format(*db->summary, *db, "output format (default: table)");
  return db;
}

int run_db_command(const DbCommand& db, std::ostream& out, std::ostream& err) {
  // Arguments first: a typo must not cost opening a store (or name a store problem instead).
  std::int64_t since_us = 0;
  std::optional<std::int64_t> since_given;
  if (!db.since.empty()) {
    const auto parsed = parse_since(db.since, db.now_us != 0 ? db.now_us : wall_clock_us());
    if (!parsed) {
      err << "fleetgw db: --since: invalid value '" << table_cell(db.since) << "': expected "
          << kSinceForms << '\n';
      return 2;
    }
    since_us = *parsed;
    since_given = since_us;
  }
  if (db.export_rows->parsed() && db.export_format == "geojson" &&
      std::find(kGeojsonTables.begin(), kGeojsonTables.end(), db.table) == kGeojsonTables.end()) {
    err << "fleetgw db export: --format geojson: table '" << table_cell(db.table)
        << "' has no geometry; --format geojson supports:";
    for (const auto name : kGeojsonTables) err << ' ' << name;
    err << '\n';
    return 2;
  }
  storage::StoreOptions options;
  if (db.db_path.empty()) {
    options = runtime::make_store_options(config::load_config(db.config_file));
  } else {
    options.path = db.db_path;
  }
  std::optional<storage::Store> store;
  if (const int rc = open_store_read_only(std::move(options), "db", store, err); rc != 0) {
    return rc;
  }
  if (db.summary->parsed()) return run_summary(*store, db, since_given, out);
  if (db.stats->parsed()) {
    const auto doc = store->stats().to_json();
    const auto format = parse_output_format(db.format).value_or(
        db.format.empty() && db.stdout_is_terminal ? OutputFormat::kTable : OutputFormat::kJson);
    if (format == OutputFormat::kJson) {
      out << doc.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << '\n';
    } else {
      write_as(format, flatten(doc), out);
    }
    return 0;
  }
  if (db.export_rows->parsed()) {
    const auto rows = db.export_format == "csv" ? export_csv(*store, db.table, since_us, out)
                      : db.export_format == "geojson"
                          ? export_rides_geojson(*store, since_us, out, err)
                          : store->export_table(db.table, since_us, out);
    err << rows << " rows\n";
    return 0;
  }
  for (const auto& [name, cmd] : db.listings) {
    if (!cmd->parsed()) continue;
    std::vector<nlohmann::json> rows;
    store->list_recent(name, since_us, db.limit,
                       [&rows](const nlohmann::json& row) { rows.push_back(row); });
    write_as(parse_output_format(db.format).value_or(OutputFormat::kTable),
             listing_table(name, rows), out);
  }
  return 0;
}

}  // namespace fleetgw::tools
