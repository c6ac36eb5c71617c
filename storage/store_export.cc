// Technician tools: Stats (row counts, outbox, disk and budget figures, evictions), the
// JSON-lines export of one table and the newest-first listings behind `fleetgw db rides|faults|
// commands|alarms`. Read-only: works on a store opened with read_only.
#include <algorithm>
#include <filesystem>
#include <limits>
#include <stdexcept>

#include "storage/schema.h"
#include "storage/store_impl.h"

namespace fleetgw::storage {
namespace fs = std::filesystem;
namespace {

struct ExportSpec {
  std::string_view table;
  std::string_view time_column;  // empty: the table has no time column
};
constexpr std::array<ExportSpec, 13> kExportSpecs = {{
    {"rides", "start_us"},
    {"fault_events", "first_seen_us"},
    {"pack_snapshots", "ts_us"},
    {"telemetry", "ts_us"},
    {"lock_events", "ts_us"},
    {"alarms", "ts_us"},
    {"zone_events", "ts_us"},
    {"command_results", "ts_us"},
    {"commands", "received_us"},
    {"seen_command_ids", "expires_at_us"},
    {"outbox", "created_us"},
    {"meta", ""},
    {"eviction_counters", ""},
}};
constexpr std::array<std::string_view, kExportSpecs.size()> kExportNames = [] {
  std::array<std::string_view, kExportSpecs.size()> names{};
  for (std::size_t i = 0; i < kExportSpecs.size(); ++i) names[i] = kExportSpecs[i].table;
  return names;
}();

std::string hex(std::span<const std::uint8_t> bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string s;
  s.reserve(bytes.size() * 2);
  for (auto b : bytes) {
    s += kDigits[b >> 4];
    s += kDigits[b & 0xf];
  }
  return s;
}

// One row of `st` as a JSON object: *_json columns embedded as JSON, blobs as lowercase hex.
nlohmann::json row_json(const Statement& st) {
  nlohmann::json row = nlohmann::json::object();
  const int ncol = st.column_count();
  for (int c = 0; c < ncol; ++c) {
    const std::string name = st.column_name(c);
    switch (st.column_type(c)) {
      case SQLITE_INTEGER:
        row[name] = st.column_int64(c);
        break;
      case SQLITE_FLOAT:
        row[name] = st.column_double(c);
        break;
      case SQLITE_TEXT: {
        std::string text = st.column_text(c);
        if (name.ends_with("_json")) {
          auto parsed = nlohmann::json::parse(text, nullptr, false);
          row[name] = parsed.is_discarded() ? nlohmann::json(text) : parsed;
        } else {
          row[name] = std::move(text);
        }
        break;
      }
      case SQLITE_BLOB:
        row[name] = hex(st.column_blob(c));
        break;
      default:
        row[name] = nullptr;
    }
  }
  return row;
}

// The listings of list_recent(): ?1 = since_us, ?2 = limit (-1: none). Fixed text, never spliced.
struct ListingSpec {
  std::string_view name;
  std::string_view sql;
};
constexpr std::array<ListingSpec, 4> kListings = {{
    {"rides", "SELECT * FROM rides WHERE start_us >= ?1 ORDER BY start_us DESC, id DESC LIMIT ?2"},
    {"faults",
     "SELECT * FROM (SELECT *, CASE event WHEN 'cleared' THEN last_seen_us ELSE first_seen_us "
     "END AS at_us FROM fault_events) WHERE at_us >= ?1 ORDER BY at_us DESC, id DESC LIMIT ?2"},
    {"alarms", "SELECT * FROM alarms WHERE ts_us >= ?1 ORDER BY ts_us DESC, id DESC LIMIT ?2"},
    {"commands",
     "SELECT * FROM ("
     " SELECT r.command_id AS command_id, coalesce(c.received_us, r.ts_us) AS at_us,"
     "  c.received_us AS received_us, c.state AS state, r.ts_us AS result_us, r.result AS result,"
     "  r.reason AS reason, r.final_state AS final_state, r.duration_ms AS duration_ms,"
     "  c.expires_at_us AS expires_at_us, r.id AS result_row"
     " FROM command_results r LEFT JOIN commands c ON c.command_id = r.command_id"
     " UNION ALL"
     " SELECT c.command_id, c.received_us, c.received_us, c.state, NULL, NULL, NULL, NULL, NULL,"
     "  c.expires_at_us, NULL"
     " FROM commands c WHERE NOT EXISTS"
     "  (SELECT 1 FROM command_results r WHERE r.command_id = c.command_id))"
     " WHERE at_us >= ?1 ORDER BY at_us DESC, result_row DESC LIMIT ?2"},
}};
constexpr std::array<std::string_view, kListings.size()> kListingNames = [] {
  std::array<std::string_view, kListings.size()> names{};
  for (std::size_t i = 0; i < kListings.size(); ++i) names[i] = kListings[i].name;
  return names;
}();

}  // namespace

nlohmann::json Stats::to_json() const {
  nlohmann::json j;
  j["path"] = path;
  j["schema_version"] = schema_version;
  for (const auto& [table, rows] : table_rows) j["tables"][table] = rows;
  j["outbox"]["in_flight"] = outbox_in_flight;
  j["outbox"]["by_priority"] = nlohmann::json::array();
  for (const auto& d : outbox) {
    j["outbox"]["by_priority"].push_back(
        {{"priority", d.priority}, {"entries", d.entries}, {"payload_bytes", d.payload_bytes}});
  }
  j["outbox"]["oldest_unsent_seq"] =
      oldest_unsent_seq ? nlohmann::json(*oldest_unsent_seq) : nlohmann::json();
  j["outbox"]["oldest_unsent_us"] =
      oldest_unsent_us ? nlohmann::json(*oldest_unsent_us) : nlohmann::json();
  j["outbox"]["oldest_unsent_kind"] =
      oldest_unsent_kind ? nlohmann::json(*oldest_unsent_kind) : nlohmann::json();
  j["outbox"]["next_seq"] = next_seq;
  j["disk"] = {{"file_bytes", file_bytes},
               {"wal_bytes", wal_bytes},
               {"page_size", page_size},
               {"page_count", page_count},
               {"freelist_pages", freelist_pages},
               {"live_bytes", live_bytes},
               {"budget_bytes", budget_bytes},
               {"configured_budget_bytes", configured_budget_bytes},
               {"wal_allowance_bytes", wal_allowance_bytes},
               {"reserve_bytes", reserve_bytes}};
  j["evictions"] = nlohmann::json::object();
  for (const auto& e : evictions) {
    j["evictions"][e.table] = {
        {"rows", e.rows},
        {"passes", e.passes},
        {"last_us", e.last_us ? nlohmann::json(*e.last_us) : nlohmann::json()}};
  }
  return j;
}

Stats Store::stats() {
  auto& db = impl_->db;
  Stats s;
  s.path = impl_->options.path;
  s.schema_version = schema_version(db);
  for (std::string_view table : kExportNames) {
    auto n = db.query_int64("SELECT count(*) FROM " + std::string(table)).value_or(0);
    s.table_rows.emplace_back(std::string(table), static_cast<std::uint64_t>(n));
  }
  s.outbox = outbox_depth();
  s.outbox_in_flight = impl_->in_flight.size();
  {
    auto st = db.cached("SELECT seq, created_us, kind FROM outbox ORDER BY seq LIMIT 1");
    if (st->step()) {
      s.oldest_unsent_seq = static_cast<std::uint64_t>(st->column_int64(0));
      s.oldest_unsent_us = st->column_int64(1);
      s.oldest_unsent_kind = st->column_text(2);
    }
  }
  std::error_code ec;
  s.file_bytes = fs::file_size(impl_->options.path, ec);
  if (ec) s.file_bytes = 0;
  s.wal_bytes = fs::file_size(impl_->options.path + "-wal", ec);
  if (ec) s.wal_bytes = 0;
  s.page_size = static_cast<std::uint64_t>(db.query_int64("PRAGMA page_size").value_or(0));
  s.page_count = static_cast<std::uint64_t>(db.query_int64("PRAGMA page_count").value_or(0));
  s.freelist_pages =
      static_cast<std::uint64_t>(db.query_int64("PRAGMA freelist_count").value_or(0));
  s.live_bytes = impl_->live_bytes();
  s.budget_bytes = impl_->budget.effective;
  s.configured_budget_bytes = impl_->budget.configured;
  s.wal_allowance_bytes = impl_->budget.wal_allowance;
  s.reserve_bytes = impl_->budget.reserve;
  s.next_seq = impl_->next_seq;
  auto st = db.cached(
      "SELECT table_name, rows, passes, last_us FROM eviction_counters ORDER BY table_name");
  while (st->step()) {
    s.evictions.push_back({st->column_text(0), static_cast<std::uint64_t>(st->column_int64(1)),
                           static_cast<std::uint64_t>(st->column_int64(2)),
                           st->column_opt_int64(3)});
  }
  return s;
}

std::span<const std::string_view> Store::exportable_tables() {
  return kExportNames;
}

namespace {

const ExportSpec& export_spec(std::string_view table) {
  for (const auto& s : kExportSpecs) {
    if (s.table == table) return s;
  }
  std::string known;
  for (auto name : kExportNames) {
    if (!known.empty()) known += ", ";
    known += name;
  }
  throw std::invalid_argument("storage: export_table: unknown table '" + std::string(table) +
                              "' (known: " + known + ")");
}

}  // namespace

std::vector<std::string> Store::export_columns(std::string_view table) {
  // The table name comes from the whitelist, never from the caller's string.
  Statement st =
      impl_->db.prepare("SELECT * FROM " + std::string(export_spec(table).table) + " LIMIT 0");
  std::vector<std::string> columns;
  for (int c = 0; c < st.column_count(); ++c) columns.push_back(st.column_name(c));
  return columns;
}

std::uint64_t Store::export_table(std::string_view table, std::int64_t since_us,
                                  const RowWriter& write_row) {
  const ExportSpec* spec = &export_spec(table);
  // The table name comes from the whitelist above, never from the caller's string.
  std::string sql = "SELECT * FROM " + std::string(spec->table);
  if (!spec->time_column.empty()) sql += " WHERE " + std::string(spec->time_column) + " >= ?";
  sql += " ORDER BY rowid";
  Statement st = impl_->db.prepare(sql);
  if (!spec->time_column.empty()) st.bind(1, since_us);
  std::uint64_t rows = 0;
  while (st.step()) {
    write_row(row_json(st));
    ++rows;
  }
  return rows;
}

std::uint64_t Store::export_table(std::string_view table, std::int64_t since_us,
                                  std::ostream& out) {
  return export_table(table, since_us,
                      [&out](const nlohmann::json& row) { out << row.dump() << '\n'; });
}

std::span<const std::string_view> Store::listings() {
  return kListingNames;
}

std::uint64_t Store::list_recent(std::string_view listing, std::int64_t since_us,
                                 std::uint64_t limit, const RowWriter& write_row) {
  const ListingSpec* spec = nullptr;
  for (const auto& l : kListings) {
    if (l.name == listing) spec = &l;
  }
  if (spec == nullptr) {
    std::string known;
    for (auto name : kListingNames) known += (known.empty() ? "" : ", ") + std::string(name);
    throw std::invalid_argument("storage: list_recent: unknown listing '" + std::string(listing) +
                                "' (known: " + known + ")");
  }
  Statement st = impl_->db.prepare(spec->sql);
  st.bind(1, since_us);
  const auto max = static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());
  st.bind(2, limit == 0 ? std::int64_t{-1} : static_cast<std::int64_t>(std::min(limit, max)));
  std::uint64_t rows = 0;
  while (st.step()) {
    nlohmann::json row = row_json(st);
    row.erase("result_row");  // ordering only
    write_row(row);
    ++rows;
  }
  return rows;
}

std::string Store::integrity_check() {
  Statement st = impl_->db.prepare("PRAGMA integrity_check");
  std::string out;
  while (st.step()) {
    if (!out.empty()) out += "; ";
    out += st.column_text(0);
  }
  return out;
}

}  // namespace fleetgw::storage
