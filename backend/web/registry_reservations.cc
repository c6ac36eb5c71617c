// Vehicle reservations (registry_reservations.h).
#include "backend/web/registry_reservations.h"

#include <stdexcept>

#include "backend/web/fleet_api.h"

namespace fleetgw::web {
namespace {

using nlohmann::json;

constexpr std::int64_t kDefaultReservationS = 900;
constexpr std::int64_t kMinReservationS = 60;
constexpr std::int64_t kMaxReservationS = 7200;

constexpr std::string_view kReservationColumns =
    "rsv.id, rsv.vehicle_id, rsv.reserved_by, rsv.started_at_us, rsv.expires_at_us, "
    "rsv.ended_at_us, rsv.end_reason";

json reservation_json(const PgResult& r, int row) {
  json j = {{"reservation_id", r.int64(row, 0)},
            {"vehicle_id", r.str(row, 1)},
            {"reserved_by", r.str(row, 2)},
            {"started_at_us", r.int64(row, 3)},
            {"expires_at_us", r.int64(row, 4)},
            {"ended_at_us", nullptr},
            {"end_reason", nullptr}};
  if (const auto e = r.int64_or_null(row, 5)) j["ended_at_us"] = *e;
  if (!r.is_null(row, 6)) j["end_reason"] = r.str(row, 6);
  return j;
}

// The reservation in force at $2 for vehicle $1 (its row locked when `lock`).
PgResult in_force_row(PgConnection& c, std::string_view vehicle_id, std::int64_t now_us,
                      bool lock) {
  const std::string sql = "SELECT " + std::string(kReservationColumns) +
                          " FROM vehicle_reservations rsv WHERE rsv.vehicle_id = $1 AND " +
                          reservation_in_force_sql("$2::bigint") +
                          " ORDER BY rsv.started_at_us DESC LIMIT 1" + (lock ? " FOR UPDATE" : "");
  const PgParam p[] = {std::string(vehicle_id), std::to_string(now_us)};
  return c.query(sql, p, "reservation in force");
}

void reservation_reply(httplib::Response& res, int status, const json& body) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  res.set_content(to_json_text(body), "application/json; charset=utf-8");
}

std::int64_t expires_in_from(const std::string& body) {
  if (body.empty()) return kDefaultReservationS;
  const json j = json::parse(body, nullptr, false);
  if (!j.is_object()) throw std::invalid_argument("expected a JSON object");
  if (!j.contains("expires_in_s")) return kDefaultReservationS;
  const json& v = j["expires_in_s"];
  if (!v.is_number_integer() || v.get<std::int64_t>() < kMinReservationS ||
      v.get<std::int64_t>() > kMaxReservationS) {
    throw std::invalid_argument("expires_in_s: a whole number of seconds in 60..7200");
  }
  return v.get<std::int64_t>();
}

}  // namespace

std::string reservation_in_force_sql(std::string_view at_expression) {
  std::string out(kReservationInForce);
  const std::string_view marker = "{at}";
  for (std::size_t p = out.find(marker); p != std::string::npos; p = out.find(marker, p)) {
    out.replace(p, marker.size(), at_expression);
    p += at_expression.size();
  }
  return out;
}

ReserveResult reserve_vehicle(PgConnection& c, std::string_view vehicle_id,
                              std::string_view operator_name, std::int64_t expires_in_s,
                              std::int64_t now_us) {
  if (expires_in_s < kMinReservationS || expires_in_s > kMaxReservationS) {
    throw std::invalid_argument("expires_in_s: a whole number of seconds in 60..7200");
  }
  PgTransaction tx(c);
  const PgParam id[] = {std::string(vehicle_id)};
  // The registry row's lock serialises reservations of one vehicle (two operators at once).
  const PgResult v = c.query(
      "SELECT v.vehicle_id, s.mode = 'VEHICLE_MODE_RIDING' FROM registry_vehicles v LEFT JOIN "
      "vehicle_state s ON s.vehicle_id = v.vehicle_id WHERE v.vehicle_id = $1 AND "
      "v.removed_at_us IS NULL FOR UPDATE OF v",
      id, "reserve: vehicle");
  if (v.rows() == 0) return {ReserveOutcome::NotFound, {}};
  if (v.boolean(0, 1)) {
    return {ReserveOutcome::Conflict, {{"error", "the vehicle is on a trip"}}};
  }
  if (const PgResult r = in_force_row(c, vehicle_id, now_us, false); r.rows() > 0) {
    return {
        ReserveOutcome::Conflict,
        {{"error", "the vehicle is reserved already"}, {"reservation", reservation_json(r, 0)}}};
  }
  const PgParam p[] = {std::string(vehicle_id), std::string(operator_name), std::to_string(now_us),
                       std::to_string(now_us + expires_in_s * 1'000'000)};
  const PgResult r = c.query(
      "INSERT INTO vehicle_reservations AS rsv (vehicle_id, reserved_by, started_at_us, "
      "expires_at_us) VALUES ($1, $2, $3, $4) RETURNING " +
          std::string(kReservationColumns),
      p, "reserve: insert");
  tx.commit();
  return {ReserveOutcome::Reserved, reservation_json(r, 0)};
}

std::optional<json> cancel_reservation(PgConnection& c, std::string_view vehicle_id,
                                       std::int64_t now_us) {
  PgTransaction tx(c);
  const PgResult found = in_force_row(c, vehicle_id, now_us, true);
  if (found.rows() == 0) return std::nullopt;
  const PgParam p[] = {found.str(0, 0), std::to_string(now_us)};
  const PgResult r = c.query(
      "UPDATE vehicle_reservations AS rsv SET ended_at_us = $2, end_reason = 'cancelled' WHERE "
      "rsv.id = $1 RETURNING " +
          std::string(kReservationColumns),
      p, "reservation: cancel");
  tx.commit();
  return reservation_json(r, 0);
}

std::optional<json> reservation_in_force(PgConnection& c, std::string_view vehicle_id,
                                         std::int64_t now_us) {
  const PgResult r = in_force_row(c, vehicle_id, now_us, false);
  if (r.rows() == 0) return std::nullopt;
  return reservation_json(r, 0);
}

json reservations_in_force(PgConnection& c, std::int64_t now_us) {
  const PgParam p[] = {std::to_string(now_us)};
  const PgResult r = c.query(
      "SELECT " + std::string(kReservationColumns) + " FROM vehicle_reservations rsv WHERE " +
          reservation_in_force_sql("$1::bigint") + " ORDER BY rsv.vehicle_id",
      p, "reservations in force");
  json out = json::array();
  for (int i = 0; i < r.rows(); ++i) out.push_back(reservation_json(r, i));
  return out;
}

void mount_reservation_routes(httplib::Server& s, PgPool& pool, Auth& auth, AuthoriseFn authorise) {
  constexpr const char* kPath = R"(/api/vehicles/([^/]+)/reservation)";
  // Listed apart from /api/vehicles/{id}: that GET takes every path below it as a vehicle id.
  s.Get("/api/reservations",
        [&pool, authorise](const httplib::Request& req, httplib::Response& res) {
          if (!authorise(req, res, Role::Viewer, "reservations")) return;
          auto c = pool.lease();
          reservation_reply(res, 200, {{"reservations", reservations_in_force(*c, now_us())}});
        });
  s.Post(kPath, [&pool, &auth, authorise](const httplib::Request& req, httplib::Response& res) {
    const std::string vehicle = req.matches[1].str();
    const auto who = authorise(req, res, Role::Operator, "vehicle_reserve");
    if (!who) return;
    try {
      const std::int64_t expires_in = expires_in_from(req.body);
      ReserveResult out;
      {
        auto c = pool.lease();
        out = reserve_vehicle(*c, vehicle, *who, expires_in, now_us());
      }
      switch (out.outcome) {
        case ReserveOutcome::Reserved:
          auth.audit(*who, req.remote_addr, "vehicle_reserve", vehicle, "ok",
                     "expires_in_s=" + std::to_string(expires_in));
          reservation_reply(res, 201, out.reservation);
          return;
        case ReserveOutcome::NotFound:
          auth.audit(*who, req.remote_addr, "vehicle_reserve", vehicle, "not_found");
          reservation_reply(res, 404, {{"error", "no such registered vehicle: " + vehicle}});
          return;
        case ReserveOutcome::Conflict:
          auth.audit(*who, req.remote_addr, "vehicle_reserve", vehicle, "conflict",
                     out.reservation.value("error", ""));
          reservation_reply(res, 409, out.reservation);
          return;
      }
    } catch (const std::invalid_argument& e) {
      auth.audit(*who, req.remote_addr, "vehicle_reserve", vehicle, "bad_request", e.what());
      reservation_reply(res, 400, {{"error", e.what()}});
    }
  });
  s.Delete(kPath, [&pool, &auth, authorise](const httplib::Request& req, httplib::Response& res) {
    const std::string vehicle = req.matches[1].str();
    const auto who = authorise(req, res, Role::Operator, "vehicle_reservation_cancel");
    if (!who) return;
    std::optional<json> ended;
    {
      auto c = pool.lease();
      ended = cancel_reservation(*c, vehicle, now_us());
    }
    auth.audit(*who, req.remote_addr, "vehicle_reservation_cancel", vehicle,
               ended ? "ok" : "not_found");
    if (!ended) {
      reservation_reply(res, 404, {{"error", "no reservation in force for " + vehicle}});
      return;
    }
    reservation_reply(res, 200, *ended);
  });
}

}  // namespace fleetgw::web
