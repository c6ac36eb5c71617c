// Console schema version 4 (issue 28): revocation lists an admin uploaded (signed offline by a
// fleet root with `fleetgw keys revoke`), as published to the bikes. Stored so every instance
// shows the list in force and refuses a version that is not newer than the last published.
#pragma once

#include <string_view>

namespace fleetgw::web {

constexpr std::string_view kRevocationSchemaV4 = R"sql(
CREATE TABLE console_revocation_lists (
  root_key_id text NOT NULL, version bigint NOT NULL CHECK (version > 0),
  signed_list bytea NOT NULL, issued_at_us bigint NOT NULL,
  revoked_serials text NOT NULL DEFAULT '', revoked_key_ids text NOT NULL DEFAULT '',
  published_at_us bigint NOT NULL, published_by text NOT NULL, address text NOT NULL,
  vehicles integer NOT NULL DEFAULT 0,
  PRIMARY KEY (root_key_id, version));
)sql";

}  // namespace fleetgw::web
