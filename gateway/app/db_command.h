// `fleetgw db stats|export`: the technician's view of the SQLite store.
//
// Contract: inspection never modifies. The store is opened read-only (SQLITE_OPEN_READONLY, no
// lock file, no migration, no move-aside), so it works while the service runs and never
// creates, moves or renames a file. A path that is missing, not SQLite, or SQLite without the
// fleetgw tables is refused with a message naming the path: exit 2. Other errors (unknown table,
// unreadable configuration...) exit 1. Output: stats as one JSON document, export as JSON lines
// on `out`, the row count on `err`.
#pragma once

#include <cstdint>
#include <memory>
#include <ostream>
#include <string>

namespace CLI {
class App;
}

namespace fleetgw::app {

struct DbCommand {
  CLI::App* command = nullptr;
  CLI::App* stats = nullptr;
  CLI::App* export_rows = nullptr;
  std::string config_file = "/etc/fleetgw/fleetgw.toml";
  std::string db_path;  // overrides storage.path of the configuration
  std::string table;
  std::int64_t since_us = 0;
};

// Registers the subcommand and its options on `app`; the returned object receives the values.
std::unique_ptr<DbCommand> add_db_command(CLI::App& app);
int run_db_command(const DbCommand& db, std::ostream& out, std::ostream& err);

}  // namespace fleetgw::app
