// Every way a command can be refused: each gets exactly one `rejected` result with the right
// reason, and not a single LOCK/UNLOCK (lock IDs or 0x760) frame reaches the bus.
#include <random>

#include "gateway/command/base64.h"
#include "tests/command/command_test_util.h"

namespace fleetgw::command::testing {
namespace {

std::string mutate_command(const std::string& signed_payload,
                           const std::function<void(v1::Command&)>& change, bool resign,
                           const Ed25519PrivateKey* key = nullptr) {
  v1::SignedCommand s;
  s.ParseFromString(signed_payload);
  v1::Command c;
  c.ParseFromString(s.command());
  change(c);
  if (resign) return sign_command(c, *key, s.key_id());
  s.set_command(c.SerializeAsString());
  return s.SerializeAsString();
}

struct Case {
  std::string name;
  std::string expected_reason;
  std::function<std::string(Rig&)> make;
  std::function<void(Rig&)> setup = nullptr;
};

std::vector<Case> cases() {
  std::vector<Case> v;
  v.push_back({"truncated", "malformed", [](Rig& r) {
                 const auto p = r.payload("seat", "unlock");
                 return p.substr(0, p.size() / 2);
               }});
  v.push_back({"random_bytes", "malformed", [](Rig&) {
                 std::mt19937 rng(1234);
                 std::string s(200, '\0');
                 for (auto& ch : s) ch = static_cast<char>(rng() & 0xFF);
                 return s;
               }});
  v.push_back({"empty", "malformed", [](Rig&) { return std::string(); }});
  v.push_back({"oversized", "malformed", [](Rig& r) {
                 v1::SignedCommand s;
                 s.ParseFromString(r.payload("seat", "unlock"));
                 s.set_key_id(std::string(5000, 'k'));
                 return s.SerializeAsString();
               }});
  v.push_back({"no_command_id", "malformed", [](Rig& r) {
                 return mutate_command(
                     r.payload("seat", "unlock"), [](v1::Command& c) { c.clear_command_id(); },
                     true, &r.key);
               }});
  v.push_back({"no_action", "malformed", [](Rig& r) {
                 return mutate_command(
                     r.payload("seat", "unlock"), [](v1::Command& c) { c.clear_action(); }, true,
                     &r.key);
               }});
  v.push_back({"no_signature", "malformed", [](Rig& r) {
                 v1::SignedCommand s;
                 s.ParseFromString(r.payload("seat", "unlock"));
                 s.clear_signature();
                 return s.SerializeAsString();
               }});
  v.push_back({"unknown_key", "unknown_key", [](Rig& r) {
                 v1::SignedCommand s;
                 s.ParseFromString(r.payload("seat", "unlock"));
                 s.set_key_id("backend-9");
                 return s.SerializeAsString();
               }});
  v.push_back({"signature_bit_flipped", "signature_invalid", [](Rig& r) {
                 v1::SignedCommand s;
                 s.ParseFromString(r.payload("seat", "unlock"));
                 std::string sig = s.signature();
                 sig[10] = static_cast<char>(sig[10] ^ 0x01);
                 s.set_signature(sig);
                 return s.SerializeAsString();
               }});
  v.push_back({"command_changed_after_signing", "signature_invalid", [](Rig& r) {
                 return mutate_command(
                     r.payload("seat", "lock"),
                     [](v1::Command& c) { c.set_action(v1::COMMAND_ACTION_UNLOCK); }, false);
               }});
  v.push_back({"signed_by_untrusted_key", "signature_invalid", [](Rig& r) {
                 const auto other = Ed25519PrivateKey::generate();
                 auto cmd = make_command(kVehicle, "seat", "unlock", r.bus.now(), r.bus.now() + 60s,
                                         random_command_id());
                 return sign_command(*cmd, other, kKeyId);
               }});
  v.push_back({"other_vehicle", "wrong_vehicle", [](Rig& r) {
                 return mutate_command(
                     r.payload("seat", "unlock"),
                     [](v1::Command& c) { c.set_vehicle_id("bike-0043"); }, true, &r.key);
               }});
  v.push_back({"expired", "expired",
               [](Rig& r) { return r.payload("seat", "unlock", {}, -60s, r.bus.now() - 120s); }});
  v.push_back({"expires_now", "expired",
               [](Rig& r) { return r.payload("seat", "unlock", {}, 0s, r.bus.now() - 10s); }});
  v.push_back({"issued_in_future", "issued_in_future",
               [](Rig& r) { return r.payload("seat", "unlock", {}, 120s, r.bus.now() + 31s); }});
  v.push_back({"valid_for_a_week", "validity_too_long", [](Rig& r) {
                 return r.payload("seat", "unlock", {}, Micros(7LL * 24 * 3600 * 1'000'000));
               }});
  v.push_back(
      {"lock_not_fitted", "lock_not_fitted", [](Rig& r) { return r.payload("wheel", "unlock"); }});
  v.push_back({"clock_unsynchronised", "clock_unsynchronised",
               [](Rig& r) { return r.payload("seat", "unlock"); },
               [](Rig& r) {
                 r.clock_synced = [](Micros) { return false; };
                 r.make_service();
               }});
  return v;
}

class Rejections : public ::testing::TestWithParam<Case> {};

TEST_P(Rejections, GetsTheRightReasonAndNothingTouchesTheBus) {
  const Case& c = GetParam();
  Rig rig;
  rig.bus.run_for(2s);  // locks and MC heard: everything is online and standing still
  if (c.setup) c.setup(rig);
  const auto states_before = rig.bus.bike().state().lock_states;
  const Micros t0 = rig.bus.now();
  const std::string payload = c.make(rig);
  const std::size_t before = rig.results.size();
  EXPECT_EQ(rig.service->on_payload(payload, rig.bus.now()), Disposition::kRejected);
  rig.bus.run_for(4s);
  ASSERT_EQ(rig.results.size(), before + 1) << c.name;
  const auto& r = rig.results.back();
  EXPECT_EQ(r.result(), v1::COMMAND_RESULT_CODE_REJECTED) << c.name;
  EXPECT_EQ(reason_code(r), c.expected_reason) << c.name << ": " << r.reason();
  EXPECT_EQ(rig.sender.command_frames_since(t0), 0u) << c.name;
  EXPECT_EQ(rig.bus.bike().state().lock_states, states_before) << c.name;
  EXPECT_EQ(rig.service->stats().accepted, 0u);
  // Stored for the uplink at priority 0.
  const auto depth = rig.store->outbox_depth();
  ASSERT_FALSE(depth.empty());
  EXPECT_EQ(depth.front().priority, 0);
}

INSTANTIATE_TEST_SUITE_P(Table, Rejections, ::testing::ValuesIn(cases()),
                         [](const auto& info) { return info.param.name; });

TEST(Rejections, ReusedIdWithDifferentContentIsReplayedAndDoesNotAct) {
  Rig rig;
  rig.bus.run_for(2s);
  const auto* first = rig.run(rig.payload("seat", "unlock", "cmd-0001"));
  ASSERT_NE(first, nullptr);
  ASSERT_EQ(first->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << first->reason();
  const Micros t0 = rig.bus.now();
  const auto* second = rig.run(rig.payload("seat", "lock", "cmd-0001"), 4s);
  ASSERT_NE(second, nullptr);
  EXPECT_EQ(second->result(), v1::COMMAND_RESULT_CODE_REJECTED);
  EXPECT_EQ(reason_code(*second), "replayed") << second->reason();
  EXPECT_EQ(rig.sender.command_frames_since(t0), 0u);
  EXPECT_EQ(rig.lock_state(0), sim::LockState::kUnlocked);
}

TEST(Rejections, SeenIdWithoutJournalEntryIsReplayed) {
  // A command id remembered as seen (e.g. journal row purged while its seen mark lives on) is
  // refused without acting.
  Rig rig;
  rig.bus.run_for(2s);
  storage::Batch b;
  b.now_us = rig.bus.now().count();
  b.commands.push_back(
      {"cmd-seen", rig.bus.now().count(), "succeeded", (rig.bus.now() + 3600s).count()});
  rig.store->write(b);
  // Drop the journal row but keep the seen mark: purge at an instant between both expiries.
  storage::Batch b2;
  b2.now_us = b.now_us;
  b2.commands.push_back(
      {"cmd-seen", rig.bus.now().count(), "succeeded", (rig.bus.now() + 10s).count()});
  rig.store->write(b2);  // seen keeps max(expiry) = +3600 s, journal now expires at +10 s
  rig.bus.run_for(20s);
  rig.store->purge_expired_commands(rig.bus.now().count());
  ASSERT_FALSE(rig.store->command("cmd-seen").has_value());
  ASSERT_TRUE(rig.store->command_seen("cmd-seen", rig.bus.now().count()));
  const Micros t0 = rig.bus.now();
  const auto* r = rig.run(rig.payload("seat", "unlock", "cmd-seen"), 3s);
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(reason_code(*r), "replayed") << r->reason();
  EXPECT_EQ(rig.sender.command_frames_since(t0), 0u);
}

TEST(Rejections, OfflineLockIsRefusedBeforeTheBus) {
  auto sc = quiet_scenario();
  sim::ScenarioEvent silence;
  silence.action = sim::Action::kSilenceNode;
  silence.node = motinova::Node::kLock3;  // steering, silent from the start
  sc.events.push_back(silence);
  Rig rig(sc);
  rig.bus.run_for(5s);
  const Micros t0 = rig.bus.now();
  const auto* r = rig.run(rig.payload("steering", "unlock"), 3s);
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_REJECTED);
  EXPECT_EQ(reason_code(*r), "lock_offline") << r->reason();
  EXPECT_EQ(rig.sender.command_frames_since(t0), 0u);
  // A whole-vehicle command needs every lock: refused as a whole, nothing moves.
  const auto* v = rig.run(rig.payload("vehicle", "unlock"), 3s);
  ASSERT_NE(v, nullptr);
  EXPECT_EQ(reason_code(*v), "lock_offline") << v->reason();
  EXPECT_EQ(rig.sender.command_frames_since(t0), 0u);
}

TEST(Rejections, JunkFloodIsRateLimited) {
  Rig rig;
  rig.tweak = [](CommandServiceConfig& c) { c.unauthenticated_results_per_minute = 5; };
  rig.make_service();
  rig.bus.run_for(2s);
  int dropped = 0;
  for (int i = 0; i < 50; ++i) {
    if (rig.service->on_payload(std::string("junk"), rig.bus.now()) == Disposition::kDropped) {
      ++dropped;
    }
  }
  EXPECT_EQ(rig.results.size(), 5u);
  EXPECT_EQ(dropped, 45);
  EXPECT_EQ(rig.service->stats().results_dropped, 45u);
  // Authenticated commands are always answered, whatever the junk did to the bucket.
  const auto* r = rig.run(rig.payload("seat", "unlock", {}, -60s, rig.bus.now() - 120s), 1s);
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(reason_code(*r), "expired");
}

TEST(Base64, RoundTripAndStrictness) {
  const std::vector<std::uint8_t> data{0, 1, 2, 250, 251, 252, 253};
  for (std::size_t n = 0; n <= data.size(); ++n) {
    const std::span<const std::uint8_t> part(data.data(), n);
    const auto enc = encode_base64(part);
    const auto dec = decode_base64(enc);
    ASSERT_TRUE(dec.has_value()) << enc;
    EXPECT_EQ(*dec, std::vector<std::uint8_t>(part.begin(), part.end()));
  }
  EXPECT_FALSE(decode_base64("AAA").has_value());
  EXPECT_FALSE(decode_base64("A===").has_value());
  EXPECT_FALSE(decode_base64("AB==").has_value());  // unused bits set
  EXPECT_FALSE(decode_base64("AA=A").has_value());
  EXPECT_FALSE(decode_base64("AA*A").has_value());
}

TEST(Ed25519, SignVerifyAndRejectBadKeys) {
  const auto key = Ed25519PrivateKey::generate();
  const std::string msg = "hello";
  const std::span<const std::uint8_t> m(reinterpret_cast<const std::uint8_t*>(msg.data()),
                                        msg.size());
  auto sig = key.sign(m);
  EXPECT_EQ(sig.size(), kEd25519SignatureBytes);
  const auto pub = Ed25519PublicKey::from_base64(key.public_key().base64());
  ASSERT_TRUE(pub.has_value());
  EXPECT_TRUE(pub->verify(m, sig));
  sig[0] ^= 1;
  EXPECT_FALSE(pub->verify(m, sig));
  EXPECT_FALSE(pub->verify(m, std::span<const std::uint8_t>(sig.data(), 10)));
  EXPECT_FALSE(Ed25519PublicKey::from_base64("AAAA").has_value());
  // PEM round trip.
  const auto again = Ed25519PrivateKey::from_pem(key.pem());
  EXPECT_EQ(again.public_key().raw(), key.public_key().raw());
  EXPECT_THROW(Ed25519PrivateKey::from_pem("not a key"), std::runtime_error);
}

TEST(Verifier, BadTrustedKeyInConfigThrowsNamingIt) {
  VerifierConfig c;
  c.vehicle_id = kVehicle;
  c.trusted_keys["ops"] = "bm90IGEga2V5";
  try {
    CommandVerifier v(c);
    FAIL() << "accepted a bad key";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ops"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace fleetgw::command::testing
