// The console's own tables, beside the ingest's (which this program only reads): operators,
// sessions, login throttling, the audit trail and alarm acknowledgements. All named `console_`.
//
// Contract: migrate_console_schema() brings the database to the newest console schema version
// (table console_schema_migrations; each missing version in its own transaction, under an
// advisory lock so several `fleetgw serve` instances starting together apply it once) and
// returns how many versions it applied. A database newer than this program is refused
// (PgError). Released versions are never edited: changes are new versions.
#pragma once

#include "backend/common/pg.h"

namespace fleetgw::web {

int migrate_console_schema(PgConnection& conn);

}  // namespace fleetgw::web
