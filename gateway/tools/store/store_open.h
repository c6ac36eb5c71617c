// Opening the SQLite store for the inspection commands (`fleetgw db ...`, `fleetgw ride plot`),
// with one mapping of the store's errors to exit codes.
//
// Contract:
//  * open_store_read_only(options, command, store, err) opens `options.path` read-only
//    (options.read_only is forced on: no lock file, no migration, no move-aside; storage/store.h)
//    into `store` and returns 0. On failure `store` stays empty, one line "fleetgw <command>:
//    <reason naming the path>" goes to `err`, and the exit code is returned: 2 for a path that
//    is missing, not SQLite or SQLite without the fleetgw tables (the user named the wrong
//    file), 1 for a store written by a newer fleetgw (SchemaTooNewError). Other exceptions
//    propagate (run_cli maps them to exit 1).
#pragma once

#include <optional>
#include <ostream>
#include <string_view>

#include "storage/store.h"

namespace fleetgw::tools {

int open_store_read_only(storage::StoreOptions options, std::string_view command,
                         std::optional<storage::Store>& store, std::ostream& err);

}  // namespace fleetgw::tools
