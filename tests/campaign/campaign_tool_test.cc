// `fleetgw campaign sign|check` through their functions: a file signed with a keygen key is
// accepted by the check with the trusted key, refused with another, and a bad file is refused
// with the field named and nothing written.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "gateway/campaign/campaign_tool.h"
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

}  // namespace
}  // namespace fleetgw::campaign
