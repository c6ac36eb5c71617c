// Revocation lists from the console (issue 28). The fleet's root keys stay offline, so the
// console never signs a list: an admin uploads the SignedRevocationList `fleetgw keys revoke`
// wrote; the server verifies it against the configured roots (--root-key) and against the last
// list it published for that root (strictly newer versions only, as the bikes judge), publishes
// it retained on every known vehicle's <prefix>/<vehicle>/revocations, stores it
// (console_revocation_lists) and audits who, when and from where. Lists as the bikes judge
// them: docs/commands.md "Revocation lists".
#include <sodium.h>
#include <spdlog/spdlog.h>

#include <fstream>
#include <memory>

#include "backend/web/admin_pages.h"
#include "backend/web/route_context.h"
#include "fleetgw/v1/keys.pb.h"

namespace fleetgw::web {
namespace {

using nlohmann::json;

// What a gateway's list may hold at most (docs/commands.md).
constexpr std::size_t kMaxListBytes = 64 * 1024;

std::string decode_base64(std::string_view text) {
  std::string raw(text.size(), '\0');
  std::size_t len = 0;
  if (sodium_base642bin(reinterpret_cast<unsigned char*>(raw.data()), raw.size(), text.data(),
                        text.size(), " \r\n", &len, nullptr, sodium_base64_VARIANT_ORIGINAL) != 0) {
    throw std::invalid_argument("not base64");
  }
  raw.resize(len);
  return raw;
}

// The ids gateways accept in lists and topics (command::is_valid_tool_id).
bool revocation_tool_id(std::string_view s) {
  if (s.empty() || s.size() > 64) return false;
  for (const char c : s) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '.' || c == '_' || c == '-';
    if (!ok) return false;
  }
  return true;
}

std::string join_serials(const v1::RevocationList& l) {
  std::string out;
  for (const auto s : l.revoked_serials()) {
    if (!out.empty()) out += ',';
    out += std::to_string(s);
  }
  return out;
}
std::string join_key_ids(const v1::RevocationList& l) {
  std::string out;
  for (const auto& k : l.revoked_key_ids()) {
    if (!out.empty()) out += ',';
    out += k;
  }
  return out;
}

json split_list(std::string_view text, bool numbers) {
  json out = json::array();
  std::size_t start = 0;
  while (start < text.size()) {
    std::size_t comma = text.find(',', start);
    if (comma == std::string_view::npos) comma = text.size();
    const std::string item(text.substr(start, comma - start));
    if (numbers) {
      out.push_back(std::stoull(item));
    } else {
      out.push_back(item);
    }
    start = comma + 1;
  }
  return out;
}

struct CheckedList {
  v1::RevocationList list;
  std::string root_key_id;
};

}  // namespace

RootKeys parse_root_keys(const std::vector<std::string>& specs) {
  RootKeys roots;
  if (sodium_init() < 0) throw std::runtime_error("libsodium cannot be initialised");
  for (const std::string& spec : specs) {
    const std::size_t eq = spec.find('=');
    const std::string id = spec.substr(0, eq);
    if (eq == std::string::npos || !revocation_tool_id(id)) {
      throw std::runtime_error("--root-key " + spec +
                               ": expected ID=BASE64 or ID=FILE.pub (ID: 1..64 of "
                               "[A-Za-z0-9._-])");
    }
    const std::string value = spec.substr(eq + 1);
    // The base64 itself (which may hold '/'), else a .pub file as `fleetgw keys root` writes
    // it (one line of base64).
    auto key_of = [](const std::string& text) {
      try {
        return decode_base64(text);
      } catch (const std::invalid_argument&) {
        return std::string();
      }
    };
    std::string raw = value.ends_with(".pub") ? std::string() : key_of(value);
    if (raw.size() != crypto_sign_PUBLICKEYBYTES) {
      std::ifstream in(value);
      std::string line;
      if (!in || !std::getline(in, line)) {
        throw std::runtime_error("--root-key " + id +
                                 ": neither a base64 raw Ed25519 public key nor a readable "
                                 ".pub file: " +
                                 value);
      }
      raw = key_of(line);
    }
    if (raw.size() != crypto_sign_PUBLICKEYBYTES) {
      throw std::runtime_error("--root-key " + id +
                               ": not a base64 raw Ed25519 public key (32 bytes)");
    }
    if (!roots.emplace(id, raw).second) {
      throw std::runtime_error("--root-key " + id + ": given twice");
    }
  }
  return roots;
}

namespace {

// The uploaded list, verified; or the reason (naming the field) it is refused.
std::variant<CheckedList, std::string> check_list(const RootKeys& roots, std::string_view bytes) {
  if (bytes.empty()) return std::string("empty file");
  if (bytes.size() > kMaxListBytes) {
    return "the list is " + std::to_string(bytes.size()) + " bytes; gateways take at most " +
           std::to_string(kMaxListBytes);
  }
  v1::SignedRevocationList sl;
  if (!sl.ParseFromArray(bytes.data(), static_cast<int>(bytes.size())) ||
      sl.revocations().empty()) {
    return std::string("not a SignedRevocationList (fleetgw keys revoke writes one)");
  }
  const auto root = roots.find(sl.root_key_id());
  if (root == roots.end()) {
    std::string known;
    for (const auto& [id, key] : roots) {
      if (!known.empty()) known += ", ";
      known += id;
    }
    return "root_key_id '" + sl.root_key_id() + "' is not one of this server's --root-key (" +
           (known.empty() ? std::string("none configured") : known) + ")";
  }
  if (sl.signature().size() != crypto_sign_BYTES ||
      crypto_sign_verify_detached(
          reinterpret_cast<const unsigned char*>(sl.signature().data()),
          reinterpret_cast<const unsigned char*>(sl.revocations().data()), sl.revocations().size(),
          reinterpret_cast<const unsigned char*>(root->second.data())) != 0) {
    return "signature: does not verify with root '" + root->first + "'";
  }
  CheckedList out;
  out.root_key_id = sl.root_key_id();
  if (!out.list.ParseFromString(sl.revocations())) {
    return std::string("revocations: not a serialized RevocationList");
  }
  if (out.list.version() == 0) return std::string("version: 0 (versions start at 1)");
  if (out.list.issued_at_us() <= 0) return std::string("issued_at_us: not set");
  for (int i = 0; i < out.list.revoked_serials_size(); ++i) {
    if (out.list.revoked_serials(i) == 0) {
      return "revoked_serials[" + std::to_string(i) + "]: 0 (serials start at 1)";
    }
  }
  for (int i = 0; i < out.list.revoked_key_ids_size(); ++i) {
    if (!revocation_tool_id(out.list.revoked_key_ids(i))) {
      return "revoked_key_ids[" + std::to_string(i) + "]: not 1..64 of [A-Za-z0-9._-]";
    }
  }
  return out;
}

// Every vehicle the console knows, as topic levels a gateway would subscribe to.
std::vector<std::string> known_vehicle_ids(PgConnection& c, int& skipped) {
  const PgResult r = c.exec(
      "SELECT vehicle_id FROM vehicle_state UNION SELECT vehicle_id FROM status "
      "UNION SELECT vehicle_id FROM registry_vehicles WHERE removed_at_us IS NULL",
      "vehicles for revocations");
  std::vector<std::string> out;
  skipped = 0;
  for (int i = 0; i < r.rows(); ++i) {
    std::string v = r.str(i, 0);
    if (revocation_tool_id(v)) {
      out.push_back(std::move(v));
    } else {
      ++skipped;  // no gateway can have this id (fleetgw run refuses it)
    }
  }
  return out;
}

std::string hex_of(std::string_view bytes) {
  std::string hex(2 * bytes.size() + 1, '\0');
  sodium_bin2hex(hex.data(), hex.size(), reinterpret_cast<const unsigned char*>(bytes.data()),
                 bytes.size());
  hex.pop_back();
  return hex;
}

std::string bytes_of_hex(std::string_view hex) {
  std::string raw(hex.size() / 2, '\0');
  std::size_t len = 0;
  if (sodium_hex2bin(reinterpret_cast<unsigned char*>(raw.data()), raw.size(), hex.data(),
                     hex.size(), nullptr, &len, nullptr) != 0) {
    throw std::runtime_error("console_revocation_lists: stored list is not hex");
  }
  raw.resize(len);
  return raw;
}

json list_row(const PgResult& r, int i) {
  return {{"root_key_id", r.str(i, 0)},
          {"version", r.int64(i, 1)},
          {"issued_at_us", r.int64(i, 2)},
          {"revoked_serials", split_list(r.text(i, 3), true)},
          {"revoked_key_ids", split_list(r.text(i, 4), false)},
          {"published_at_us", r.int64(i, 5)},
          {"published_by", r.str(i, 6)},
          {"address", r.str(i, 7)},
          {"vehicles", r.int64(i, 8)}};
}

constexpr std::string_view kListColumns =
    "root_key_id, version, issued_at_us, revoked_serials, revoked_key_ids, published_at_us, "
    "published_by, address, vehicles";

// Publishes `payload` on every known vehicle's revocations topic; the number of vehicles.
int publish_to_fleet(RouteContext& ctx, const std::string& payload) {
  int skipped = 0;
  std::vector<std::string> vehicles;
  {
    auto c = ctx.pool.lease();
    vehicles = known_vehicle_ids(*c, skipped);
  }
  std::vector<std::string> topics;
  topics.reserve(vehicles.size());
  for (const auto& v : vehicles)
    topics.push_back(ctx.options.topic_prefix + "/" + v + "/revocations");
  ctx.hub->publish_retained(topics, payload);
  if (skipped > 0) spdlog::warn("serve: {} vehicle ids cannot be topic levels: skipped", skipped);
  return static_cast<int>(topics.size());
}

json keys_seen(PgConnection& c) {
  // The keys and delegations this console signed with, and how often (the bikes' results
  // come back bound to them): what an admin may want to revoke.
  const PgResult r = c.exec(
      "SELECT key_id, delegation_serial, count(*), max(issued_at_us), "
      "count(*) FILTER (WHERE reason LIKE 'revoked%') FROM console_commands "
      "GROUP BY key_id, delegation_serial ORDER BY max(issued_at_us) DESC LIMIT 50",
      "keys seen");
  json out = json::array();
  for (int i = 0; i < r.rows(); ++i) {
    out.push_back({{"key_id", r.str(i, 0)},
                   {"delegation_serial", r.is_null(i, 1) ? json(nullptr) : json(r.int64(i, 1))},
                   {"commands", r.int64(i, 2)},
                   {"last_used_us", r.int64(i, 3)},
                   {"refused_revoked", r.int64(i, 4)}});
  }
  return out;
}

}  // namespace

void add_revocation_routes(httplib::Server& s, RouteContext& ctx) {
  auto roots = std::make_shared<const RootKeys>(parse_root_keys(ctx.options.root_keys));

  s.Get("/api/revocations", [&ctx, roots](const httplib::Request& req, httplib::Response& res) {
    if (!ctx.authorise(req, res, Role::Admin, "revocations")) return;
    auto c = ctx.pool.lease();
    const PgResult in_force =
        c->exec("SELECT DISTINCT ON (root_key_id) " + std::string(kListColumns) +
                    " FROM console_revocation_lists ORDER BY root_key_id, version DESC",
                "revocation lists in force");
    const PgResult history = c->exec("SELECT " + std::string(kListColumns) +
                                         " FROM console_revocation_lists ORDER BY "
                                         "published_at_us DESC LIMIT 20",
                                     "revocation history");
    json lists = json::array(), past = json::array(), root_ids = json::array();
    for (int i = 0; i < in_force.rows(); ++i) lists.push_back(list_row(in_force, i));
    for (int i = 0; i < history.rows(); ++i) past.push_back(list_row(history, i));
    for (const auto& [id, key] : *roots) root_ids.push_back(id);
    send_json(res, 200,
              {{"roots", root_ids},
               {"in_force", lists},
               {"history", past},
               {"publishing", ctx.hub != nullptr},
               {"this_server", ctx.signer ? ctx.signer->describe() : json(nullptr)},
               {"keys_seen", keys_seen(*c)}});
  });

  // {"list_base64": "..."}: the file `fleetgw keys revoke` wrote, as the browser read it.
  s.Post("/api/revocations", [&ctx, roots](const httplib::Request& req, httplib::Response& res) {
    const auto session = ctx.authorise(req, res, Role::Admin, "revocations_publish");
    if (!session) return;
    auto refuse = [&](int status, const std::string& target, const std::string& result,
                      const std::string& why) {
      ctx.auth.audit(session->operator_name, req.remote_addr, "revocations_publish", target, result,
                     why);
      send_error(res, status, why);
    };
    if (ctx.hub == nullptr) {
      refuse(503, "", "commands_off",
             "publishing is off: this fleetgw serve runs without --broker and --signing-key");
      return;
    }
    if (roots->empty()) {
      refuse(503, "", "no_roots", "no --root-key configured: this server cannot verify a list");
      return;
    }
    const json body = json::parse(req.body, nullptr, false);
    std::string bytes;
    if (!body.is_object() || !body.contains("list_base64") || !body["list_base64"].is_string()) {
      refuse(400, "", "bad_request",
             "expected {\"list_base64\": the file fleetgw keys revoke wrote}");
      return;
    }
    try {
      bytes = decode_base64(body["list_base64"].get<std::string>());
    } catch (const std::invalid_argument&) {
      refuse(400, "", "bad_request", "list_base64: not base64");
      return;
    }
    auto checked = check_list(*roots, bytes);
    if (auto* why = std::get_if<std::string>(&checked)) {
      refuse(400, "", "bad_request", *why);
      return;
    }
    const CheckedList& l = std::get<CheckedList>(checked);
    const std::string target = l.root_key_id + "/" + std::to_string(l.list.version());
    {
      auto c = ctx.pool.lease();
      const PgParam p[] = {l.root_key_id};
      const PgResult last = c->query(
          "SELECT version, encode(signed_list, 'hex') FROM console_revocation_lists WHERE "
          "root_key_id = $1 ORDER BY version DESC LIMIT 1",
          p, "last revocation list");
      if (last.rows() == 1) {
        const auto held = static_cast<std::uint64_t>(last.int64(0, 0));
        if (held == l.list.version() && bytes_of_hex(last.text(0, 1)) == bytes) {
          refuse(409, target, "already_published",
                 "version " + std::to_string(held) + " of root '" + l.root_key_id +
                     "' is already published (Publish again re-sends it)");
          return;
        }
        if (l.list.version() <= held) {
          refuse(409, target, "not_newer",
                 "version " + std::to_string(l.list.version()) + " is not newer than version " +
                     std::to_string(held) + " of root '" + l.root_key_id +
                     "' published before; the bikes would refuse it (fleetgw keys revoke "
                     "--version " +
                     std::to_string(held + 1) + ")");
          return;
        }
      }
    }
    int vehicles = 0;
    try {
      vehicles = publish_to_fleet(ctx, bytes);
    } catch (const std::runtime_error& e) {
      refuse(502, target, "not_published", e.what());
      return;
    }
    const std::string summary = "serials [" + join_serials(l.list) + "] key ids [" +
                                join_key_ids(l.list) + "] to " + std::to_string(vehicles) +
                                " vehicles";
    {
      auto c = ctx.pool.lease();
      const PgParam p[] = {l.root_key_id,
                           std::to_string(l.list.version()),
                           "\\x" + hex_of(bytes),
                           std::to_string(l.list.issued_at_us()),
                           join_serials(l.list),
                           join_key_ids(l.list),
                           std::to_string(now_us()),
                           session->operator_name,
                           req.remote_addr,
                           std::to_string(vehicles)};
      c->query(
          "INSERT INTO console_revocation_lists (root_key_id, version, signed_list, issued_at_us, "
          "revoked_serials, revoked_key_ids, published_at_us, published_by, address, vehicles) "
          "VALUES ($1, $2::bigint, $3::bytea, $4::bigint, $5, $6, $7::bigint, $8, $9, "
          "$10::integer) ON CONFLICT DO NOTHING",
          p, "store revocation list");
    }
    ctx.auth.audit(session->operator_name, req.remote_addr, "revocations_publish", target, "ok",
                   summary);
    send_json(res, 200,
              {{"root_key_id", l.root_key_id},
               {"version", l.list.version()},
               {"revoked_serials", l.list.revoked_serials()},
               {"revoked_key_ids", l.list.revoked_key_ids()},
               {"vehicles", vehicles}});
  });

  // The lists in force again, retained on every vehicle known now (bikes added since).
  s.Post("/api/revocations/republish", [&ctx](const httplib::Request& req, httplib::Response& res) {
    const auto session = ctx.authorise(req, res, Role::Admin, "revocations_republish");
    if (!session) return;
    if (ctx.hub == nullptr) {
      ctx.auth.audit(session->operator_name, req.remote_addr, "revocations_republish", "",
                     "commands_off");
      send_error(res, 503, "publishing is off: no --broker");
      return;
    }
    std::vector<std::pair<std::string, std::string>> lists;
    {
      auto c = ctx.pool.lease();
      const PgResult r = c->exec(
          "SELECT DISTINCT ON (root_key_id) root_key_id || '/' || version, "
          "encode(signed_list, 'hex') FROM console_revocation_lists "
          "ORDER BY root_key_id, version DESC",
          "lists to republish");
      for (int i = 0; i < r.rows(); ++i)
        lists.emplace_back(r.str(i, 0), bytes_of_hex(r.text(i, 1)));
    }
    json done = json::array();
    for (const auto& [target, bytes] : lists) {
      try {
        const int n = publish_to_fleet(ctx, bytes);
        ctx.auth.audit(session->operator_name, req.remote_addr, "revocations_republish", target,
                       "ok", std::to_string(n) + " vehicles");
        done.push_back({{"list", target}, {"vehicles", n}});
      } catch (const std::runtime_error& e) {
        ctx.auth.audit(session->operator_name, req.remote_addr, "revocations_republish", target,
                       "not_published", e.what());
        send_error(res, 502, e.what());
        return;
      }
    }
    send_json(res, 200, {{"republished", done}});
  });
}

}  // namespace fleetgw::web
