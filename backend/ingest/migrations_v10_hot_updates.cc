// Migration 10 (issue 25; migrations.h): room on every page of vehicle_state, so the upsert each
// batch makes per vehicle replaces the row on its own page (a HOT update: no new index entry,
// less WAL) instead of moving it to another page.
//
// Why: a batch replaces the state of each of its vehicles (one upsert per vehicle and batch,
// the largest per-batch cost after the range merge, docs/backend.md). At the default fillfactor
// of 100 a page of states is full and about half of those updates moved their row (measured:
// 2,000 vehicles, 40,000 upserts, backend CPU 11.0 us per upsert at 100, 9.2 at 70). Pages
// written from now on keep the room (existing pages get it when rewritten): no row is touched.
#include "backend/ingest/migrations.h"

namespace fleetgw::ingest {

std::string_view migration_v10_sql() {
  return R"sql(
ALTER TABLE vehicle_state SET (fillfactor = 70);
)sql";
}

}  // namespace fleetgw::ingest
