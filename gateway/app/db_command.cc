#include "gateway/app/db_command.h"

#include <CLI/CLI.hpp>

#include "gateway/config/config.h"
#include "gateway/runtime/recorder.h"
#include "storage/schema.h"
#include "storage/store.h"

namespace fleetgw::app {

std::unique_ptr<DbCommand> add_db_command(CLI::App& app) {
  auto db = std::make_unique<DbCommand>();
  db->command = app.add_subcommand("db", "inspect the SQLite store, read-only (technicians)");
  db->command->require_subcommand(1);
  db->stats = db->command->add_subcommand("stats", "row counts, outbox depth, size, evictions");
  db->export_rows = db->command->add_subcommand("export", "one JSON object per row");
  for (auto* c : {db->stats, db->export_rows}) {
    c->add_option("--config", db->config_file, "configuration file (for storage.path)");
    c->add_option("--db", db->db_path, "database file (overrides the configuration)");
  }
  db->export_rows->add_option("--table", db->table, "table to export")->required();
  db->export_rows->add_option("--since", db->since_us,
                              "only rows at or after this time (us since epoch)");
  return db;
}

int run_db_command(const DbCommand& db, std::ostream& out, std::ostream& err) {
  storage::StoreOptions options;
  if (db.db_path.empty()) {
    options = runtime::make_store_options(config::load_config(db.config_file));
  } else {
    options.path = db.db_path;
  }
  options.read_only = true;
  std::optional<storage::Store> store;
  try {
    store.emplace(std::move(options));
  } catch (const storage::NotAStoreError& e) {
    err << "fleetgw db: " << e.what() << '\n';
    return 2;
  } catch (const storage::SchemaTooNewError& e) {
    err << "fleetgw db: " << e.what() << '\n';
    return 1;
  }
  if (db.stats->parsed()) {
    out << store->stats().to_json().dump(2) << '\n';
  } else {
    const auto rows = store->export_table(db.table, db.since_us, out);
    err << rows << " rows\n";
  }
  return 0;
}

}  // namespace fleetgw::app
