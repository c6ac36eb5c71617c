// One definite result per command, never spoofable (issue 11, item 5): every result is bound
// to the exact signed bytes (CommandResult.command_sha256) or, for a payload that failed
// authentication, to that whole payload only (payload_sha256). A forged payload with a chosen
// command id -- even a byte-for-byte copy of the genuine command with a broken signature --
// neither blocks the genuine command nor produces a result its sender would take for its own.
// Plus the schema side: the new fields are a compatible change an old reader survives.
#include <google/protobuf/descriptor.h>
#include <google/protobuf/dynamic_message.h>

#include <algorithm>
#include <fstream>
#include <sstream>

#include "gateway/command/sha256.h"
#include "tests/command/command_test_util.h"
#include "tests/uplink/proto_compat.h"

namespace fleetgw::command::testing {
namespace {

namespace pb = google::protobuf;

SentCommand sent_of(const std::string& signed_payload) {
  v1::SignedCommand s;
  s.ParseFromString(signed_payload);
  return {signed_payload, sha256(s.command())};
}

std::size_t result_rows(storage::Store& store, std::string_view id) {
  std::size_t n = 0;
  store.export_table("command_results", 0, [&](const nlohmann::json& row) {
    if (row.value("command_id", "") == id) ++n;
  });
  return n;
}

TEST(ResultBinding, ForgedPayloadsWithTheGenuineIdNeitherBlockNorAnswerIt) {
  Rig rig;
  rig.bus.run_for(2s);
  const std::string genuine = rig.payload("seat", "unlock", "cmd-victim");
  const SentCommand sent = sent_of(genuine);
  for (const auto& forged : {broken_copy(genuine), forged_other(genuine)}) {
    EXPECT_EQ(rig.service->on_payload(forged, rig.bus.now()), Disposition::kRejected);
    const auto& r = rig.results.back();
    EXPECT_EQ(r.command_id(), "cmd-victim");
    EXPECT_EQ(reason_code(r), "signature_invalid") << r.reason();
    EXPECT_TRUE(r.command_sha256().empty());
    EXPECT_EQ(r.payload_sha256(), sha256(forged));
    EXPECT_FALSE(result_answers(r, "cmd-victim", sent));
  }
  // Not journaled, not seen, no row: the genuine command is judged as if they never came.
  EXPECT_FALSE(rig.store->command("cmd-victim").has_value());
  EXPECT_FALSE(rig.store->command_seen("cmd-victim", rig.bus.now().count()));
  EXPECT_EQ(result_rows(*rig.store, "cmd-victim"), 0u);

  const Micros t0 = rig.bus.now();
  const auto* r = rig.run(genuine);
  ASSERT_NE(r, nullptr);
  // rig.run returns the first result with the id since delivery: the genuine one.
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << r->reason();
  EXPECT_EQ(r->command_sha256(), sent.command_sha256);
  EXPECT_TRUE(r->payload_sha256().empty());
  EXPECT_GT(rig.sender.lock_writes(0, t0), 0u);
  EXPECT_EQ(rig.lock_state(0), sim::LockState::kUnlocked);
  // Of everything published under this id, exactly one result answers the sender.
  int answering = 0;
  for (const auto& res : rig.results) {
    if (result_answers(res, "cmd-victim", sent)) {
      ++answering;
      EXPECT_EQ(res.result(), v1::COMMAND_RESULT_CODE_SUCCEEDED);
    }
  }
  EXPECT_EQ(answering, 1);
  EXPECT_EQ(result_rows(*rig.store, "cmd-victim"), 1u);

  // Afterwards: a forged copy is still only rejected; the genuine redelivery gets the stored
  // success again (not a forgery's rejection), still bound, and nothing moves.
  const Micros t1 = rig.bus.now();
  EXPECT_EQ(rig.service->on_payload(broken_copy(genuine), rig.bus.now()), Disposition::kRejected);
  EXPECT_EQ(rig.service->on_payload(genuine, rig.bus.now()), Disposition::kDuplicateAnswered);
  EXPECT_EQ(rig.results.back().result(), v1::COMMAND_RESULT_CODE_SUCCEEDED);
  EXPECT_TRUE(result_answers(rig.results.back(), "cmd-victim", sent));
  EXPECT_EQ(rig.sender.command_frames_since(t1), 0u);
}

TEST(ResultBinding, EveryResultOfAnAuthenticCommandCarriesTheDigestOfItsSignedBytes) {
  Rig rig;
  rig.bus.run_for(2s);
  for (const auto& p : {rig.payload("seat", "unlock"), rig.payload("wheel", "unlock"),
                        rig.payload("seat", "lock", {}, -60s, rig.bus.now() - 120s)}) {
    const auto* r = rig.run(p, 5s);
    ASSERT_NE(r, nullptr);
    EXPECT_EQ(r->command_sha256(), sent_of(p).command_sha256) << r->reason();
    EXPECT_EQ(r->command_sha256().size(), 32u);
    EXPECT_TRUE(r->stored());
  }
  // A payload that is not even a SignedCommand is bound to its bytes only.
  rig.service->on_payload(std::string("junk"), rig.bus.now());
  EXPECT_EQ(rig.results.back().payload_sha256(), sha256("junk"));
  EXPECT_TRUE(rig.results.back().command_sha256().empty());
}

// --- schema ---------------------------------------------------------------------------------

const pb::FieldDescriptorProto* field(const pb::FileDescriptorSet& set, std::string_view message,
                                      std::string_view name) {
  return fleetgw::testing::find_field(set, message, name);
}

TEST(ResultBindingSchema, NewFieldsAreACompatibleAdditionRecordedInTheSnapshot) {
  const auto current = fleetgw::testing::current_fleetgw_descriptors();
  const auto snapshot = fleetgw::testing::load_snapshot(FLEETGW_PROTO_SNAPSHOT);
  EXPECT_TRUE(fleetgw::testing::compare(snapshot, current).empty());
  for (const auto& [name, number] : std::vector<std::pair<std::string, int>>{
           {"command_sha256", 8}, {"stored", 9}, {"payload_sha256", 10}}) {
    const auto* now = field(current, "CommandResult", name);
    const auto* recorded = field(snapshot, "CommandResult", name);
    ASSERT_NE(now, nullptr) << name;
    ASSERT_NE(recorded, nullptr) << name << " missing from the committed snapshot";
    EXPECT_EQ(now->number(), number) << name;
    EXPECT_EQ(recorded->number(), number) << name;
  }
}

TEST(ResultBindingSchema, AReaderOfTheOldSchemaParsesANewResult) {
  // The old CommandResult: today's without fields 8-10.
  auto old_set = fleetgw::testing::current_fleetgw_descriptors();
  for (auto& f : *old_set.mutable_file()) {
    for (auto& m : *f.mutable_message_type()) {
      if (m.name() != "CommandResult") continue;
      auto* fields = m.mutable_field();
      fields->erase(std::remove_if(fields->begin(), fields->end(),
                                   [](const auto& fd) { return fd.number() >= 8; }),
                    fields->end());
    }
  }
  pb::DescriptorPool pool;
  const std::string error = fleetgw::testing::build_pool(old_set, pool);
  ASSERT_TRUE(error.empty()) << error;
  const auto* old_type = pool.FindMessageTypeByName("fleetgw.v1.CommandResult");
  ASSERT_NE(old_type, nullptr);
  ASSERT_EQ(old_type->FindFieldByName("command_sha256"), nullptr);

  v1::CommandResult r;
  r.set_command_id("cmd-1");
  r.set_result(v1::COMMAND_RESULT_CODE_SUCCEEDED);
  r.set_reason("fine");
  r.set_command_sha256(sha256("x"));
  r.set_stored(true);
  r.set_payload_sha256(sha256("y"));
  pb::DynamicMessageFactory factory(&pool);
  std::unique_ptr<pb::Message> old(factory.GetPrototype(old_type)->New());
  ASSERT_TRUE(old->ParseFromString(r.SerializeAsString()));
  const auto* refl = old->GetReflection();
  EXPECT_EQ(refl->GetString(*old, old_type->FindFieldByName("command_id")), "cmd-1");
  EXPECT_EQ(refl->GetString(*old, old_type->FindFieldByName("reason")), "fine");
  EXPECT_EQ(refl->GetEnumValue(*old, old_type->FindFieldByName("result")),
            v1::COMMAND_RESULT_CODE_SUCCEEDED);
  // And an old result (no digest) reads as unbound: an operator tool never takes it as its own.
  v1::CommandResult from_old = r;
  from_old.clear_command_sha256();
  from_old.clear_payload_sha256();
  EXPECT_FALSE(result_answers(from_old, "cmd-1", SentCommand{"payload", sha256("x")}));
}

}  // namespace
}  // namespace fleetgw::command::testing
