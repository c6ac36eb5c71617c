// Start-up recovery answers bound to the command (issue 11, item 5): a command the previous
// run journaled as "executing" is answered by recover() with a result whose command_sha256 is
// the digest of the exact signed bytes, as a live result is -- the journal keeps the digest
// (schema v3) -- so `fleetgw command`, which accepts only bound results, takes it.
#include "gateway/command/sha256.h"
#include "storage/schema.h"
#include "storage/sqlite.h"
#include "tests/command/command_test_util.h"

namespace fleetgw::command::testing {
namespace {

std::string signed_digest(const std::string& signed_payload) {
  v1::SignedCommand s;
  EXPECT_TRUE(s.ParseFromString(signed_payload));
  return sha256(s.command());
}

TEST(JournalRecovery, ResultAfterRestartCarriesTheCommandDigest) {
  Rig rig;
  rig.bus.run_for(2s);
  const std::string p = rig.payload("battery", "unlock", "cmd-recover-sha");
  const std::string digest = signed_digest(p);
  ASSERT_EQ(digest.size(), 32u);
  ASSERT_EQ(rig.service->on_payload(p, rig.bus.now()), Disposition::kStarted);
  rig.bus.run_for(100ms);
  ASSERT_TRUE(rig.results.empty()) << "still executing when the process dies";
  ASSERT_EQ(rig.store->command("cmd-recover-sha")->command_sha256, digest)
      << "the journal keeps the digest from the first write";

  rig.restart();  // service, node and store gone; reopened on the same file
  ASSERT_EQ(rig.service->recover(rig.bus.now()), 1u);
  ASSERT_EQ(rig.results.size(), 1u);
  const auto& r = rig.results[0];
  EXPECT_EQ(r.command_id(), "cmd-recover-sha");
  EXPECT_EQ(r.result(), v1::COMMAND_RESULT_CODE_TIMEOUT);
  EXPECT_EQ(r.command_sha256(), digest) << "bound to the signed bytes like a live result";
  EXPECT_TRUE(r.stored());
  EXPECT_TRUE(result_answers(r, "cmd-recover-sha", {p, digest}));
  // The final journal state keeps the digest too (a later duplicate answers bound).
  const auto entry = rig.store->command("cmd-recover-sha");
  ASSERT_TRUE(entry.has_value());
  EXPECT_EQ(entry->state, "timeout");
  EXPECT_EQ(entry->command_sha256, digest);
}

// A journal row written before schema v3 has no digest: recovery still answers (unbound, the
// operator tool ignores it, as it would any result of an older gateway) and does not fail.
TEST(JournalRecovery, RowWithoutDigestFromAnOlderVersionIsStillFinished) {
  Rig rig;
  rig.bus.run_for(2s);
  {
    storage::Database db(rig.db_path.string());
    db.exec(
        "INSERT INTO commands (command_id, received_us, state, expires_at_us, command_sha256) "
        "VALUES ('cmd-old', " +
        std::to_string(rig.bus.now().count()) + ", 'executing', " +
        std::to_string(rig.bus.now().count() + 60'000'000) + ", NULL)");
  }
  rig.restart();
  ASSERT_EQ(rig.service->recover(rig.bus.now()), 1u);
  ASSERT_EQ(rig.results.size(), 1u);
  EXPECT_EQ(rig.results[0].command_id(), "cmd-old");
  EXPECT_EQ(rig.results[0].result(), v1::COMMAND_RESULT_CODE_TIMEOUT);
  EXPECT_TRUE(rig.results[0].command_sha256().empty());
  EXPECT_EQ(rig.store->command("cmd-old")->state, "timeout");
}

}  // namespace
}  // namespace fleetgw::command::testing
