// `fleetgw campaign sign|check` through their functions: a file signed with a keygen key is
// accepted by the check with the trusted key, refused with another, and a bad file is refused
// with the field named and nothing written.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "fleetgw/v1/keys.pb.h"
#include "gateway/campaign/campaign_tool.h"
#include "gateway/command/delegation.h"
#include "gateway/command/ed25519.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::campaign {
namespace {

constexpr const char* kCampaign = R"(
id = "cells-1hz"
version = 1
signals = ["bms.cells.cells_mv[0]", "bms.cells.cells_mv[1]"]
disk_budget_bytes = 1048576
start = 2026-01-01T00:00:00Z
end = 2026-03-01T00:00:00Z
[trigger]
kind = "always"
[sampling]
kind = "every"
period_ms = 1000
[target]
all_vehicles = true
)";

TEST(CampaignTool, SignThenCheck) {
  testing::TempDir dir;
  const auto key = command::Ed25519PrivateKey::generate();
  key.write_pem(dir.path() / "eng.pem");
  std::ofstream(dir.path() / "c.toml") << kCampaign;
  std::ostringstream out, err;
  CampaignSignOptions sign{.file = dir.path() / "c.toml",
                           .key_pem = dir.path() / "eng.pem",
                           .key_id = "",
                           .version = 2,
                           .issued_at = motinova::Micros{1'767'225'600'000'000},
                           .out = dir.path() / "c.signed"};
  ASSERT_EQ(run_campaign_sign(sign, out, err), 0) << err.str();
  EXPECT_NE(out.str().find("'cells-1hz' version 2 signed by 'eng'"), std::string::npos);
  EXPECT_NE(out.str().find("at most 7200 samples/h"), std::string::npos) << out.str();

  CampaignCheckOptions check{.signed_file = dir.path() / "c.signed",
                             .trusted_keys = {{"eng", key.public_key().base64()}},
                             .vehicle_id = "bike-1",
                             .groups = {},
                             .now = motinova::Micros{1'767'225'600'000'000}};
  std::ostringstream out2, err2;
  EXPECT_EQ(run_campaign_check(check, out2, err2), 0) << out2.str() << err2.str();
  EXPECT_EQ(out2.str().rfind("accepted: version 2", 0), 0u) << out2.str();
  check.trusted_keys = {{"eng", command::Ed25519PrivateKey::generate().public_key().base64()}};
  std::ostringstream out3, err3;
  EXPECT_EQ(run_campaign_check(check, out3, err3), 1);
  EXPECT_EQ(out3.str().rfind("refused (signature_invalid)", 0), 0u) << out3.str();
  check.now = motinova::Micros{1'772'323'200'000'000};  // 2026-03-01: ended
  check.trusted_keys = {{"eng", key.public_key().base64()}};
  std::ostringstream out4, err4;
  EXPECT_EQ(run_campaign_check(check, out4, err4), 1);
  EXPECT_EQ(out4.str().rfind("refused (expired)", 0), 0u) << out4.str();
  // A 1 MiB disk budget on a gateway whose store has 2 MiB: over the quarter campaigns may take.
  check.now = motinova::Micros{1'767'225'600'000'000};
  check.store_budget_bytes = 2u << 20;
  std::ostringstream out5, err5;
  EXPECT_EQ(run_campaign_check(check, out5, err5), 1);
  EXPECT_EQ(out5.str().rfind("refused (over_budget)", 0), 0u) << out5.str();
}

TEST(CampaignTool, AnUnknownSignalIsRefusedAndNothingWritten) {
  testing::TempDir dir;
  command::Ed25519PrivateKey::generate().write_pem(dir.path() / "eng.pem");
  std::string text = kCampaign;
  text.replace(text.find("cells_mv[1]"), 11, "cells_mv[99]");
  std::ofstream(dir.path() / "c.toml") << text;
  std::ostringstream out, err;
  CampaignSignOptions sign{.file = dir.path() / "c.toml",
                           .key_pem = dir.path() / "eng.pem",
                           .key_id = "",
                           .version = 0,
                           .issued_at = motinova::Micros{1'767'225'600'000'000},
                           .out = dir.path() / "c.signed"};
  EXPECT_EQ(run_campaign_sign(sign, out, err), 1);
  EXPECT_NE(err.str().find("c.toml: signals[1]: unknown signal 'bms.cells.cells_mv[99]'"),
            std::string::npos)
      << err.str();
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "c.signed"));
}

// Issue 28 in the tool: `campaign sign --delegation` and `campaign check` with the root keys
// judge a delegated campaign as the bike does (the six refusal names), not as unknown_key.
TEST(CampaignTool, CheckJudgesADelegatedCampaignLikeTheBike) {
  testing::TempDir dir;
  const auto root = command::Ed25519PrivateKey::generate();
  const auto delegate = command::Ed25519PrivateKey::generate();
  delegate.write_pem(dir.path() / "console-1.pem");
  std::ofstream(dir.path() / "c.toml") << kCampaign;
  const motinova::Micros now{1'767'225'600'000'000};  // 2026-01-01
  const motinova::Micros hour{3'600'000'000};
  auto write_delegation = [&](std::string_view action, motinova::Micros not_after) {
    v1::Delegation d;
    d.set_serial(11);
    d.set_key_id("console-1");
    const auto pub = delegate.public_key();
    d.set_public_key(std::string(pub.raw().begin(), pub.raw().end()));
    d.add_actions(std::string(action));
    d.add_groups("berlin-north");
    d.set_not_before_us((now - hour).count());
    d.set_not_after_us(not_after.count());
    d.set_issued_at_us((now - 2 * hour).count());
    std::ofstream(dir.path() / "d.signed", std::ios::binary | std::ios::trunc)
        << command::sign_delegation(d, root, "root-1");
  };
  auto sign = [&]() {
    std::ostringstream out, err;
    CampaignSignOptions o{.file = dir.path() / "c.toml",
                          .key_pem = dir.path() / "console-1.pem",
                          .key_id = "",
                          .version = 1,
                          .issued_at = now,
                          .out = dir.path() / "c.signed",
                          .delegation = dir.path() / "d.signed"};
    return run_campaign_sign(o, out, err) == 0 ? std::string() : err.str();
  };
  CampaignCheckOptions check{.signed_file = dir.path() / "c.signed",
                             .trusted_keys = {},
                             .vehicle_id = "bike-1",
                             .groups = {"berlin-north"},
                             .now = now,
                             .root_keys = {{"root-1", root.public_key().base64()}}};
  auto verdict = [&](const CampaignCheckOptions& o) {
    std::ostringstream out, err;
    const int rc = run_campaign_check(o, out, err);
    return std::to_string(rc) + " " + out.str() + err.str();
  };

  write_delegation("campaign", now + hour);
  ASSERT_EQ(sign(), "");
  EXPECT_EQ(verdict(check).rfind("0 accepted: version 1", 0), 0u) << verdict(check);
  auto without_roots = check;
  without_roots.root_keys.clear();
  EXPECT_EQ(verdict(without_roots).rfind("1 refused (unknown_key)", 0), 0u);
  auto other_vehicle = check;
  other_vehicle.groups = {"paris"};
  EXPECT_EQ(verdict(other_vehicle).rfind("1 refused (out_of_scope)", 0), 0u);
  auto later = check;
  later.now = now + 2 * hour;
  EXPECT_EQ(verdict(later).rfind("1 refused (delegation_expired)", 0), 0u) << verdict(later);
  auto forged = check;
  forged.root_keys = {{"root-1", command::Ed25519PrivateKey::generate().public_key().base64()}};
  EXPECT_EQ(verdict(forged).rfind("1 refused (delegation_invalid)", 0), 0u);

  // The root's published revocation list, as the bike would hold it.
  v1::RevocationList list;
  list.set_version(1);
  list.set_issued_at_us(now.count());
  list.add_revoked_serials(11);
  std::ofstream(dir.path() / "r.signed", std::ios::binary)
      << command::sign_revocation_list(list, root, "root-1");
  auto revoked = check;
  revoked.revocations = dir.path() / "r.signed";
  EXPECT_EQ(verdict(revoked).rfind("1 refused (revoked)", 0), 0u) << verdict(revoked);

  write_delegation("zones", now + hour);
  ASSERT_EQ(sign(), "");
  EXPECT_EQ(verdict(check).rfind("1 refused (out_of_scope)", 0), 0u) << verdict(check);
}

}  // namespace
}  // namespace fleetgw::campaign
