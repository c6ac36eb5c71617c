// The campaign page's API (issue 29): what collection campaigns delivered, read from the
// ingest's campaign_samples (migration 7; docs/campaigns.md), for every role (viewer and up).
//   GET /api/campaigns                      campaigns seen: per (id, version) vehicles, samples,
//                                           signals, first and last sample
//   GET /api/campaigns/detail?id=&version=  per vehicle: samples, last sample, signals
//   GET /api/campaigns/samples?id=&version=&signal=[&vehicle=][&limit=]   one signal's samples
//   GET /api/campaigns/samples.csv?id=&version=[&signal=][&vehicle=]      the samples as CSV
// Ids and signals are parameters of the query (a campaign id is its author's string); every SQL
// value a parameter; every string out a JSON string or a CSV cell under the formula rule.
// Without migration 7 yet (an older ingest schema) the lists are empty and say so.
#include <charconv>
#include <string>

#include "backend/web/csv_cell.h"
#include "backend/web/route_context.h"

namespace fleetgw::web {
namespace {

using nlohmann::json;

constexpr int kMaxCampaigns = 200;
constexpr int kMaxSampleRows = 5000;
constexpr int kMaxCsvRows = 100000;

json campaign_opt_int(const PgResult& r, int row, int col) {
  const auto v = r.int64_or_null(row, col);
  return v ? json(*v) : json(nullptr);
}

bool have_campaign_table(PgConnection& c) {
  const PgResult r = c.exec("SELECT to_regclass('campaign_samples') IS NOT NULL", "campaigns?");
  return r.rows() == 1 && r.boolean(0, 0);
}

std::optional<std::int64_t> parse_int(const std::string& s) {
  std::int64_t v = 0;
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || p != s.data() + s.size()) return std::nullopt;
  return v;
}

// ?id= and ?version= of a request; nullopt (and a 400 written) when missing or malformed.
std::optional<std::pair<std::string, std::int64_t>> campaign_key(const httplib::Request& req,
                                                                 httplib::Response& res) {
  // value_or, not a conditional copy of the optional: gcc 12 at -O3 warns maybe-uninitialized
  // on the latter (-Werror in the product tree).
  const std::int64_t version =
      req.has_param("version") ? parse_int(req.get_param_value("version")).value_or(-1) : -1;
  if (!req.has_param("id") || req.get_param_value("id").empty() || version < 0) {
    send_error(res, 400, "expected ?id=CAMPAIGN&version=N (N a whole number >= 0)");
    return std::nullopt;
  }
  return std::make_pair(req.get_param_value("id"), version);
}

json campaign_list(PgConnection& c) {
  const PgResult r = c.exec(
      "SELECT campaign_id, campaign_version, count(DISTINCT vehicle_id), count(*), "
      "array_to_json(array_agg(DISTINCT signal ORDER BY signal)), min(sampled_at_us), "
      "max(sampled_at_us), max(committed_at_us) FROM campaign_samples "
      "GROUP BY campaign_id, campaign_version ORDER BY max(committed_at_us) DESC LIMIT " +
          std::to_string(kMaxCampaigns),
      "campaign list");
  json out = json::array();
  for (int i = 0; i < r.rows(); ++i) {
    json signals = json::parse(r.str(i, 4), nullptr, false);
    out.push_back({{"id", r.str(i, 0)},
                   {"version", campaign_opt_int(r, i, 1)},
                   {"vehicles", campaign_opt_int(r, i, 2)},
                   {"samples", campaign_opt_int(r, i, 3)},
                   {"signals", signals.is_discarded() ? json::array() : signals},
                   {"first_sample_us", campaign_opt_int(r, i, 5)},
                   {"last_sample_us", campaign_opt_int(r, i, 6)},
                   {"last_received_us", campaign_opt_int(r, i, 7)}});
  }
  return out;
}

json campaign_vehicles(PgConnection& c, const std::string& id, std::int64_t version) {
  const PgParam p[] = {id, std::to_string(version)};
  const PgResult r = c.query(
      "SELECT vehicle_id, count(*), max(sampled_at_us), max(committed_at_us), "
      "array_to_json(array_agg(DISTINCT signal ORDER BY signal)), "
      "count(*) FILTER (WHERE invalid), max(trigger_at_us) FROM campaign_samples "
      "WHERE campaign_id = $1 AND campaign_version = $2::bigint "
      "GROUP BY vehicle_id ORDER BY vehicle_id LIMIT 10000",
      p, "campaign vehicles");
  json out = json::array();
  for (int i = 0; i < r.rows(); ++i) {
    json signals = json::parse(r.str(i, 4), nullptr, false);
    out.push_back({{"vehicle_id", r.str(i, 0)},
                   {"samples", campaign_opt_int(r, i, 1)},
                   {"last_sample_us", campaign_opt_int(r, i, 2)},
                   {"last_received_us", campaign_opt_int(r, i, 3)},
                   {"signals", signals.is_discarded() ? json::array() : signals},
                   {"invalid", campaign_opt_int(r, i, 5)},
                   {"last_trigger_us", campaign_opt_int(r, i, 6)}});
  }
  return out;
}

// The samples of a campaign version, optionally one signal and/or one vehicle, oldest first.
PgResult campaign_samples(PgConnection& c, const httplib::Request& req, const std::string& id,
                          std::int64_t version, int limit) {
  const PgParam p[] = {
      id, std::to_string(version),
      req.has_param("signal") ? PgParam(req.get_param_value("signal")) : PgParam(std::nullopt),
      req.has_param("vehicle") ? PgParam(req.get_param_value("vehicle")) : PgParam(std::nullopt),
      std::to_string(limit)};
  return c.query(
      "SELECT sampled_at_us, vehicle_id, signal, value, text, invalid, trigger_at_us, "
      "campaign_id, campaign_version FROM campaign_samples "
      "WHERE campaign_id = $1 AND campaign_version = $2::bigint "
      "AND ($3::text IS NULL OR signal = $3) AND ($4::text IS NULL OR vehicle_id = $4) "
      "ORDER BY sampled_at_us, vehicle_id, sequence, sample_index LIMIT $5::int",
      p, "campaign samples");
}

}  // namespace

void add_campaign_routes(httplib::Server& s, RouteContext& ctx) {
  s.Get("/api/campaigns", [&ctx](const httplib::Request& req, httplib::Response& res) {
    if (!ctx.authorise(req, res, Role::Viewer, "campaigns")) return;
    auto c = ctx.pool.lease();
    if (!have_campaign_table(*c)) {
      send_json(res, 200, {{"available", false}, {"campaigns", json::array()}});
      return;
    }
    send_json(res, 200, {{"available", true}, {"campaigns", campaign_list(*c)}});
  });
  s.Get("/api/campaigns/detail", [&ctx](const httplib::Request& req, httplib::Response& res) {
    if (!ctx.authorise(req, res, Role::Viewer, "campaign")) return;
    const auto key = campaign_key(req, res);
    if (!key) return;
    auto c = ctx.pool.lease();
    json vehicles =
        have_campaign_table(*c) ? campaign_vehicles(*c, key->first, key->second) : json::array();
    if (vehicles.empty()) {
      send_error(res, 404, "no samples of this campaign version");
      return;
    }
    send_json(res, 200,
              {{"id", key->first}, {"version", key->second}, {"vehicles", std::move(vehicles)}});
  });
  s.Get("/api/campaigns/samples", [&ctx](const httplib::Request& req, httplib::Response& res) {
    if (!ctx.authorise(req, res, Role::Viewer, "campaign")) return;
    const auto key = campaign_key(req, res);
    if (!key) return;
    if (!req.has_param("signal")) {
      send_error(res, 400, "expected &signal=NAME (fleetgw signals)");
      return;
    }
    int limit = kMaxSampleRows;
    if (req.has_param("limit")) {
      const auto l = parse_int(req.get_param_value("limit"));
      if (!l || *l < 1 || *l > kMaxSampleRows) {
        send_error(res, 400, "limit must be 1 to " + std::to_string(kMaxSampleRows));
        return;
      }
      limit = static_cast<int>(*l);
    }
    auto c = ctx.pool.lease();
    json rows = json::array();
    if (have_campaign_table(*c)) {
      const PgResult r = campaign_samples(*c, req, key->first, key->second, limit + 1);
      for (int i = 0; i < r.rows() && i < limit; ++i) {
        json value = nullptr;
        if (!r.is_null(i, 3)) value = std::stod(r.str(i, 3));
        rows.push_back({campaign_opt_int(r, i, 0), r.str(i, 1), value,
                        r.is_null(i, 4) ? json(nullptr) : json(r.str(i, 4)), r.boolean(i, 5),
                        campaign_opt_int(r, i, 6)});
      }
      const bool more = r.rows() > limit;
      send_json(res, 200,
                {{"id", key->first},
                 {"version", key->second},
                 {"signal", req.get_param_value("signal")},
                 {"fields", {"t_us", "vehicle_id", "value", "text", "invalid", "trigger_at_us"}},
                 {"samples", std::move(rows)},
                 {"truncated", more}});
      return;
    }
    send_json(res, 200, {{"samples", rows}, {"truncated", false}});
  });
  s.Get("/api/campaigns/samples.csv", [&ctx](const httplib::Request& req, httplib::Response& res) {
    if (!ctx.authorise(req, res, Role::Viewer, "campaign_csv")) return;
    const auto key = campaign_key(req, res);
    if (!key) return;
    auto c = ctx.pool.lease();
    if (!have_campaign_table(*c)) {
      send_error(res, 404, "no campaign samples in this database");
      return;
    }
    const PgResult r = campaign_samples(*c, req, key->first, key->second, kMaxCsvRows);
    std::string csv =
        "campaign_id,campaign_version,vehicle_id,signal,sampled_at_us,value,text,invalid,"
        "trigger_at_us\r\n";
    for (int i = 0; i < r.rows(); ++i) {
      csv += csv_text_cell(r.str(i, 7)) + "," + r.str(i, 8) + "," + csv_text_cell(r.str(i, 1)) +
             "," + csv_text_cell(r.str(i, 2)) + "," + r.str(i, 0) + "," +
             (r.is_null(i, 3) ? "" : r.str(i, 3)) + "," +
             (r.is_null(i, 4) ? "" : csv_text_cell(r.str(i, 4))) + "," +
             (r.boolean(i, 5) ? "true" : "false") + "," + (r.is_null(i, 6) ? "" : r.str(i, 6)) +
             "\r\n";
    }
    res.status = 200;
    res.set_header("Cache-Control", "no-store");
    // A fixed file name: the campaign id is the author's string, not for a header.
    res.set_header("Content-Disposition", "attachment; filename=\"campaign-samples.csv\"");
    if (r.rows() >= kMaxCsvRows) res.set_header("X-Truncated", std::to_string(kMaxCsvRows));
    res.set_content(csv, "text/csv; charset=utf-8");
  });
}

}  // namespace fleetgw::web
