// Migration 11 (issue 25; migrations.h): a batch appends its sequence ranges instead of merging
// them into the stored ones inside its transaction; a compaction merges them later, many
// batches at once.
//
// Why: the merge (DELETE of the touching stored ranges, gaps and islands, INSERT) was the
// largest cost a batch had beyond its rows' COPYs: one statement per batch touching ~1,500-2,300
// (vehicle, store) ranges of 20,000 rows, 9-12 µs of server CPU per range on a quiet machine
// (docs/backend.md, Figures). In a drain a vehicle's range of one batch rarely continues its
// stored one (the sessions' streams interleave), so growing ranges in place did not pay off.
// Now a batch COPYs one row per (vehicle, store) and range into sequence_ranges_new (no index,
// no unique key: nothing for two workers to wait on), and fleet_compact_sequence_ranges() moves
// them into sequence_ranges_merged (what sequence_ranges was: merged, keyed) every so many
// ranges, each vehicle's stored range rewritten once per compaction instead of once per batch.
//
// What readers see does not change: sequence_ranges is now a view merging both tables on the
// fly (adjacent, overlapping, duplicate rows merged exactly; a range ending at 2^63-1 too), and
// sequence_gaps the holes between its rows, as before.
// Every stored range is kept (the table is renamed, not copied).
//
// The compaction deletes exactly the appended rows its statement reads (DELETE ... RETURNING,
// one snapshot): a batch that commits while it runs keeps its rows for the next one. One
// compaction at a time (a transaction-level advisory lock, tried, not waited for); a
// compaction that loses the race returns 0. A range a compaction and a batch both hold is
// merged twice, harmlessly: the view merges overlaps.
#include "backend/ingest/migrations.h"

namespace fleetgw::ingest {

std::string_view migration_v11_sql() {
  return R"sql(
DROP VIEW sequence_gaps;
ALTER TABLE sequence_ranges RENAME TO sequence_ranges_merged;
ALTER INDEX sequence_ranges_pkey RENAME TO sequence_ranges_merged_pkey;

CREATE TABLE sequence_ranges_new (
  vehicle_id text NOT NULL, store_id text NOT NULL, first_seq bigint NOT NULL,
  last_seq bigint NOT NULL, CHECK (first_seq >= 1 AND last_seq >= first_seq));

-- Both tables' ranges merged per (vehicle, store): range_agg merges overlapping and adjacent
-- ranges. As numeric ranges [first, last + 1): a bigint range would overflow at 2^63-1. (Half
-- the server time of the same merge by window functions: 17 against 34 ms over 18,000 rows.)
CREATE VIEW sequence_ranges AS
  SELECT vehicle_id, store_id, lower(r)::bigint AS first_seq, (upper(r) - 1)::bigint AS last_seq
  FROM (SELECT vehicle_id, store_id,
               unnest(range_agg(numrange(first_seq, last_seq::numeric + 1))) AS r
        FROM (SELECT vehicle_id, store_id, first_seq, last_seq FROM sequence_ranges_merged
              UNION ALL
              SELECT vehicle_id, store_id, first_seq, last_seq FROM sequence_ranges_new) a
        GROUP BY vehicle_id, store_id) m;

CREATE VIEW sequence_gaps AS
  SELECT vehicle_id, store_id, prev_last + 1 AS first_missing, first_seq - 1 AS last_missing
  FROM (SELECT vehicle_id, store_id, first_seq,
               coalesce(lag(last_seq) OVER w, 0) AS prev_last
        FROM sequence_ranges
        WINDOW w AS (PARTITION BY vehicle_id, store_id ORDER BY first_seq)) r
  WHERE first_seq > prev_last + 1;

-- Moves every appended range it sees into sequence_ranges_merged (merged with the stored ranges
-- it touches); returns the appended rows moved (0 when another compaction holds the lock).
CREATE FUNCTION fleet_compact_sequence_ranges() RETURNS bigint LANGUAGE plpgsql AS $$
DECLARE moved bigint;
BEGIN
  IF NOT pg_try_advisory_xact_lock(7363453106150743) THEN RETURN 0; END IF;
  WITH n AS (
    DELETE FROM sequence_ranges_new RETURNING vehicle_id, store_id, first_seq, last_seq),
  gone AS (
    DELETE FROM sequence_ranges_merged r USING n
    WHERE r.vehicle_id = n.vehicle_id AND r.store_id = n.store_id
      AND r.first_seq - 1 <= n.last_seq AND r.last_seq >= n.first_seq - 1
    RETURNING r.vehicle_id, r.store_id, r.first_seq, r.last_seq),
  alls AS (
    SELECT DISTINCT vehicle_id, store_id, first_seq, last_seq FROM gone
    UNION ALL SELECT vehicle_id, store_id, first_seq, last_seq FROM n),
  marked AS (
    SELECT *, CASE WHEN first_seq - 1 <= max(last_seq) OVER (PARTITION BY vehicle_id, store_id
                ORDER BY first_seq, last_seq ROWS BETWEEN UNBOUNDED PRECEDING AND 1 PRECEDING)
              THEN 0 ELSE 1 END AS starts
    FROM alls),
  grouped AS (
    SELECT *, sum(starts) OVER (PARTITION BY vehicle_id, store_id ORDER BY first_seq, last_seq
                                ROWS UNBOUNDED PRECEDING) AS island
    FROM marked),
  merged AS (
    INSERT INTO sequence_ranges_merged (vehicle_id, store_id, first_seq, last_seq)
    SELECT vehicle_id, store_id, min(first_seq), max(last_seq) FROM grouped
    GROUP BY vehicle_id, store_id, island)
  SELECT count(*) INTO moved FROM n;
  RETURN moved;
END $$;
)sql";
}

}  // namespace fleetgw::ingest
