// `fleetgw db stats|export|summary|rides|faults|commands|alarms`: the technician's view of the
// SQLite store.
//
// Contract: inspection never modifies. The store is opened read-only (SQLITE_OPEN_READONLY, no
// lock file, no migration, no move-aside), so it works while the service runs and never
// creates, moves or renames a file. A path that is missing, not SQLite, or SQLite without the
// fleetgw tables is refused with a message naming the path: exit 2. A bad `--since` (see
// time_arg.h) exits 2 naming the option and the value, before the store is opened. Other
// errors (unknown table, unreadable configuration...) exit 1.
// Output on `out`:
//  * stats: `--format json` one JSON document; `table` and `csv` the same document flattened
//    to key/value rows (table_format.h). Without --format: table on a terminal, JSON otherwise
//    (scripts that read `db stats` keep their JSON).
//  * export: one table in insertion order, the row count on `err`. `--format jsonl` (the
//    default, byte for byte what export always printed): one JSON object per line. `--format
//    csv`: RFC 4180 (table_format.h), a header of the table's columns in schema order, one
//    record per row, numbers in full precision, *_json columns as their JSON text, blobs as
//    lowercase hex; every string exactly as stored (quoted when it must be). `--format
//    geojson` (rides only, db_geojson.h): a FeatureCollection, one Feature per ride with its
//    track as a LineString; any other table exits 2 naming the tables it supports.
//  * summary: db_summary.h, over `--since` (default: the whole store). `--format table` (the
//    default): the sentence, a blank line, then one row per area; `json`: one document;
//    `csv`: the document flattened to key,value rows.
//  * rides|faults|commands|alarms: newest first, at most `--limit` rows (default 20, 0 = all),
//    `--format table` (default), `json` or `csv` (db_listings.h, table_format.h).
#pragma once

#include <cstdint>
#include <memory>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

namespace CLI {
class App;
}

namespace fleetgw::tools {

struct DbCommand {
  CLI::App* command = nullptr;
  CLI::App* stats = nullptr;
  CLI::App* export_rows = nullptr;
  CLI::App* summary = nullptr;
  std::vector<std::pair<std::string, CLI::App*>> listings;  // rides, faults, commands, alarms
  std::string config_file = "/etc/fleetgw/fleetgw.toml";
  std::string db_path;  // overrides storage.path of the configuration
  std::string table;
  std::string since;                    // as typed; parsed by parse_since()
  std::string format;                   // table|json|csv; empty: the subcommand's default
  std::string export_format = "jsonl";  // jsonl|csv|geojson
  std::uint64_t limit = 20;
  bool stdout_is_terminal = false;  // stats' default format
  std::int64_t now_us = 0;          // for relative --since values; 0: the wall clock
};

// Registers the subcommand and its options on `app`; the returned object receives the values.
std::unique_ptr<DbCommand> add_db_command(CLI::App& app);
int run_db_command(const DbCommand& db, std::ostream& out, std::ostream& err);

}  // namespace fleetgw::tools
