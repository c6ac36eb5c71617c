// Remote diagnostics (issue 29) against the simulated bike in lockstep: each block read returns
// the decoded block, a silent node answers node_offline, a delegation without the action is
// refused out_of_scope, the lifetime records are captured and read without a bus request, and
// nothing is ever written to a node.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "fleetgw/v1/keys.pb.h"
#include "gateway/command/delegation.h"
#include "gateway/command/diag_blocks.h"
#include "tests/command/command_test_util.h"
#include "tests/uplink/proto_compat.h"

namespace fleetgw::command::testing {
namespace {

v1::Command diag_command(v1::DiagnosticBlock block, Micros now, std::string_view lock = {},
                         bool captured = false) {
  v1::Command c;
  c.set_command_id(random_command_id());
  c.set_vehicle_id(kVehicle);
  c.set_issued_at_us(now.count());
  c.set_expires_at_us((now + 60s).count());
  c.mutable_diagnostic_read()->set_block(block);
  if (!lock.empty()) c.mutable_diagnostic_read()->set_lock_kind(std::string(lock));
  c.mutable_diagnostic_read()->set_last_captured(captured);
  return c;
}

std::string diag_payload(Rig& rig, v1::DiagnosticBlock block, std::string_view lock = {},
                         bool captured = false) {
  return sign_command(diag_command(block, rig.bus.now(), lock, captured), rig.key, kKeyId);
}

// The decoded value of signal `name` in the result (first message that has it).
const v1::DiagnosticValue* diag_value(const v1::CommandResult& r, std::string_view name) {
  for (const auto& m : r.diagnostic().messages()) {
    for (const auto& v : m.values()) {
      if (v.name() == name) return &v;
    }
  }
  return nullptr;
}

std::string diag_names(const v1::CommandResult& r) {
  std::string out;
  for (const auto& m : r.diagnostic().messages()) {
    for (const auto& v : m.values()) out += v.name() + " ";
  }
  return out;
}

double diag_number(const v1::CommandResult& r, std::string_view name) {
  const auto* v = diag_value(r, name);
  EXPECT_NE(v, nullptr) << name << " not in: " << diag_names(r);
  if (v == nullptr || !v->has_value_e6()) return -1e9;
  return static_cast<double>(v->value_e6()) / 1e6;
}

std::string diag_text(const v1::CommandResult& r, std::string_view name) {
  const auto* v = diag_value(r, name);
  EXPECT_NE(v, nullptr) << name << " not in: " << diag_names(r);
  return v == nullptr ? std::string() : v->text();
}

// Every frame the gateway sent towards another node (not its own 0x760 broadcasts) since
// `since` is a read request: a diagnostic read never writes.
void expect_only_reads_since(const BusSender& sender, Micros since) {
  for (const auto& s : sender.sent) {
    if (s.at < since || s.frame.can_id == node::ids::kIotBroadcast) continue;
    EXPECT_EQ(s.frame.mode, motinova::Mode::kRead)
        << "write to 0x" << std::hex << s.frame.can_id << " function 0x"
        << static_cast<int>(s.frame.function);
    EXPECT_EQ(s.frame.data.size(), 0u);
  }
}

struct DiagRig : Rig {
  DiagRig() : Rig() { bus.run_for(3s); }  // every node heard, handshakes done
  const v1::CommandResult* read(v1::DiagnosticBlock block, std::string_view lock = {},
                                bool captured = false) {
    return run(diag_payload(*this, block, lock, captured));
  }
};

TEST(Diag, EachBlockReadReturnsTheDecodedBlock) {
  DiagRig rig;
  const auto& sc = rig.bus.bike().scenario();
  const Micros t0 = rig.bus.now();
  for (const auto& spec : diag_blocks()) {
    const std::string_view lock = spec.block == v1::DIAGNOSTIC_BLOCK_LOCK_MODEL ? "frame" : "";
    const auto* r = rig.read(spec.block, lock);
    ASSERT_NE(r, nullptr) << spec.name;
    EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << spec.name << ": " << r->reason();
    ASSERT_TRUE(r->has_diagnostic()) << spec.name;
    EXPECT_EQ(r->diagnostic().block(), spec.name);
    EXPECT_EQ(r->diagnostic().source(), "bus");
    ASSERT_GE(r->diagnostic().messages_size(), 1) << spec.name;
    const auto& m = r->diagnostic().messages(0);
    EXPECT_EQ(m.message(), spec.steps.front().answer_name) << spec.name;
    EXPECT_GT(m.values_size(), 0) << spec.name;
    EXPECT_FALSE(m.data().empty());
    EXPECT_GT(m.heard_at_us(), 0);
    EXPECT_FALSE(r->command_sha256().empty());
  }
  // What the blocks say is what the simulated bike is.
  auto read = [&](v1::DiagnosticBlock b, std::string_view lock = {}) {
    const auto* r = rig.read(b, lock);
    EXPECT_NE(r, nullptr);
    return r == nullptr ? v1::CommandResult() : *r;
  };
  const auto settings = read(v1::DIAGNOSTIC_BLOCK_MC_SETTINGS);
  EXPECT_EQ(diag_number(settings, "mc.settings.speed_limit_kmh"), sc.speed_limit_kmh);
  EXPECT_EQ(diag_number(settings, "mc.settings.speed_limit_offset_kmh"), 0);
  EXPECT_EQ(settings.diagnostic().node(), "mc");
  const auto params = read(v1::DIAGNOSTIC_BLOCK_MC_PARAMS);
  EXPECT_EQ(diag_number(params, "mc.params2.p1"), 9);
  EXPECT_EQ(diag_number(params, "mc.params2.p3"), 120);
  const auto cells = read(v1::DIAGNOSTIC_BLOCK_BMS_CELLS);
  const double cell1 = diag_number(cells, "bms.cells.cells_mv[0]");
  EXPECT_GT(cell1, 3000);
  EXPECT_LT(cell1, 4300);
  EXPECT_EQ(diag_number(cells, "bms.cells.cells_mv[13]"), 0);  // a 13S pack
  EXPECT_EQ(diag_text(read(v1::DIAGNOSTIC_BLOCK_OBC_MODEL), "obc.device_info.fw"), sc.obc.fw);
  EXPECT_EQ(diag_text(read(v1::DIAGNOSTIC_BLOCK_BMS_MODEL), "bms.device_info.serial"),
            sc.bms.serial);
  EXPECT_EQ(diag_text(read(v1::DIAGNOSTIC_BLOCK_MC_MODEL), "mc.device_info.model"), sc.mc.model);
  const auto lock = read(v1::DIAGNOSTIC_BLOCK_LOCK_MODEL, "frame");  // LOCK 2 in the sim
  EXPECT_EQ(lock.diagnostic().node(), "lock2");
  EXPECT_EQ(diag_text(lock, "lock2.device_info.serial"), sc.lock.serial + "-2");
  const auto pack = read(v1::DIAGNOSTIC_BLOCK_PACK_LIFETIME);
  EXPECT_EQ(diag_number(pack, "bms.pack_stats.soh_pct"), sc.soh_pct);
  EXPECT_EQ(diag_number(pack, "bms.pack_stats.cycles"), sc.cycles);
  const auto life = read(v1::DIAGNOSTIC_BLOCK_MC_LIFETIME);
  ASSERT_EQ(life.diagnostic().messages_size(), 2) << life.diagnostic().note();
  EXPECT_EQ(life.diagnostic().messages(0).message(), "mc_lifetime_1");
  EXPECT_EQ(life.diagnostic().messages(1).message(), "mc_lifetime_2");
  EXPECT_EQ(life.diagnostic().messages(0).can_id(), 0x715u);
  EXPECT_EQ(life.diagnostic().messages(0).command(), 0xA230u);
  EXPECT_GE(diag_number(life, "mc.lifetime_1.power_on_count"), 400);
  EXPECT_GT(diag_number(life, "mc.lifetime_1.operating_time_min"), 0);
  EXPECT_EQ(diag_number(life, "mc.lifetime_2.mos_short_count"), 0);
  EXPECT_TRUE(life.diagnostic().note().empty()) << life.diagnostic().note();
  // Read-only: every frame of these reads was a read request; the bike's state is unchanged.
  expect_only_reads_since(rig.sender, t0);
  EXPECT_EQ(rig.sender.mc_writes(), 0u);
  EXPECT_EQ(rig.sender.command_frames_since(Micros{0}), 0u);
  EXPECT_EQ(rig.bus.bike().state().speed_limit_offset_kmh, 0);
}

TEST(Diag, TheMcLifetimeRecordCountsFaultsTheMcRaised) {
  auto sc = quiet_scenario();
  // Over-current (low bit 0x0001) twice and MOS short (high bit 0x0001) once.
  for (const auto& [at, bits] :
       std::vector<std::pair<Micros, std::uint32_t>>{{1s, 0x0001}, {3s, 0x0001}, {3s, 0x10000}}) {
    sim::ScenarioEvent on;
    on.at = at;
    on.action = sim::Action::kFault;
    on.node = motinova::Node::kMc;
    on.bits = bits;
    sim::ScenarioEvent off = on;
    off.at = at + 500ms;
    off.action = sim::Action::kClear;
    sc.events.push_back(on);
    sc.events.push_back(off);
  }
  Rig rig(sc);
  rig.bus.run_for(5s);
  const auto* r = rig.run(diag_payload(rig, v1::DIAGNOSTIC_BLOCK_MC_LIFETIME));
  ASSERT_NE(r, nullptr);
  ASSERT_EQ(r->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << r->reason();
  EXPECT_EQ(diag_number(*r, "mc.lifetime_1.over_current_count"), 2);
  EXPECT_EQ(diag_number(*r, "mc.lifetime_1.under_voltage_count"), 0);
  EXPECT_EQ(diag_number(*r, "mc.lifetime_2.mos_short_count"), 1);
}

TEST(Diag, ASilentNodeAnswersNodeOffline) {
  auto sc = quiet_scenario();
  sim::ScenarioEvent silence;
  silence.at = 2s;
  silence.action = sim::Action::kSilenceNode;
  silence.node = motinova::Node::kBms;
  sc.events.push_back(silence);
  silence.node = motinova::Node::kMc;
  sc.events.push_back(silence);
  Rig rig(sc);
  rig.bus.run_for(3s);
  for (const auto block : {v1::DIAGNOSTIC_BLOCK_BMS_STATUS, v1::DIAGNOSTIC_BLOCK_PACK_LIFETIME,
                           v1::DIAGNOSTIC_BLOCK_MC_SETTINGS, v1::DIAGNOSTIC_BLOCK_MC_LIFETIME}) {
    const Micros sent = rig.bus.now();
    const auto* r = rig.run(diag_payload(rig, block));
    ASSERT_NE(r, nullptr) << v1::DiagnosticBlock_Name(block);
    EXPECT_EQ(r->result(), v1::COMMAND_RESULT_CODE_TIMEOUT) << r->reason();
    EXPECT_EQ(reason_code(*r), "node_offline") << r->reason();
    EXPECT_EQ(r->diagnostic().messages_size(), 0);
    // Spec 3.7: retried every 200 ms, given up after 1 s -- 5 requests per step, then the
    // answer. Polls of the same ID queued ahead of it (each given up after 1 s too: at most 6 on
    // the BMS's 0x762) may delay the start; mc_lifetime has no poll on 0x751.
    EXPECT_EQ(r->diagnostic().requests_sent(), 5u) << r->reason();
    EXPECT_LE(r->duration_ms(), 7100u);
    EXPECT_GE(r->duration_ms(), 1000u);
    if (block == v1::DIAGNOSTIC_BLOCK_MC_LIFETIME) {
      EXPECT_LE(r->duration_ms(), 1100u);
    }
    expect_only_reads_since(rig.sender, sent);
  }
  // The OBC still answers.
  const auto* obc = rig.run(diag_payload(rig, v1::DIAGNOSTIC_BLOCK_OBC_MODEL));
  ASSERT_NE(obc, nullptr);
  EXPECT_EQ(obc->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << obc->reason();
}

TEST(Diag, LifetimeRecordsAreCapturedAndReadWithoutABusRequest) {
  DiagRig rig;
  // Nothing seen yet: a definite answer, nothing sent.
  const Micros t0 = rig.bus.now();
  const auto* none = rig.read(v1::DIAGNOSTIC_BLOCK_MC_LIFETIME, {}, true);
  ASSERT_NE(none, nullptr);
  EXPECT_EQ(none->result(), v1::COMMAND_RESULT_CODE_FAILED);
  EXPECT_EQ(reason_code(*none), "not_captured") << none->reason();
  EXPECT_EQ(rig.sender.frames(0x751, 0x12, t0), 0u);
  // A service dongle's read (CDL 0x751) makes the MC send its records: captured in passing.
  for (const std::uint8_t fn : {0x12, 0x19}) {
    for (const auto& can : motinova::segment(node::read_request(0x751, fn))) {
      rig.bus.send(can, sim::VirtualBus::kExternal);
    }
    rig.bus.run_for(100ms);
  }
  // Captured from the dongle's read alone, before any diagnostic read.
  const auto* dongle = rig.read(v1::DIAGNOSTIC_BLOCK_MC_LIFETIME, {}, true);
  ASSERT_NE(dongle, nullptr);
  EXPECT_EQ(dongle->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << dongle->reason();
  ASSERT_EQ(dongle->diagnostic().messages_size(), 2);
  const std::string dongle_data = dongle->diagnostic().messages(0).data();
  const auto* bus_read = rig.read(v1::DIAGNOSTIC_BLOCK_MC_LIFETIME);
  ASSERT_NE(bus_read, nullptr);
  const v1::CommandResult from_bus = *bus_read;
  const Micros t1 = rig.bus.now();
  const auto* captured = rig.read(v1::DIAGNOSTIC_BLOCK_MC_LIFETIME, {}, true);
  ASSERT_NE(captured, nullptr);
  EXPECT_EQ(captured->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << captured->reason();
  EXPECT_EQ(captured->diagnostic().source(), "captured");
  EXPECT_EQ(captured->diagnostic().requests_sent(), 0u);
  ASSERT_EQ(captured->diagnostic().messages_size(), 2);
  EXPECT_EQ(captured->diagnostic().messages(0).data(), from_bus.diagnostic().messages(0).data());
  EXPECT_EQ(rig.sender.frames(0x751, 0x12, t1), 0u);  // no bus request
  // Kept in the store (written at the node's next tick): after a restart, the same record.
  rig.bus.run_for(100ms);
  rig.restart();
  const auto* after = rig.read(v1::DIAGNOSTIC_BLOCK_MC_LIFETIME, {}, true);
  ASSERT_NE(after, nullptr);
  EXPECT_EQ(after->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << after->reason();
  ASSERT_GE(after->diagnostic().messages_size(), 1);
  // The last one written: a changed record is written at most once a minute.
  const std::string& kept = after->diagnostic().messages(0).data();
  EXPECT_TRUE(kept == from_bus.diagnostic().messages(0).data() || kept == dongle_data);
  // The pack statistics are captured too (here from a read; the poller's 0x5400 as well).
  ASSERT_NE(rig.read(v1::DIAGNOSTIC_BLOCK_PACK_LIFETIME), nullptr);
  const auto* pack = rig.read(v1::DIAGNOSTIC_BLOCK_PACK_LIFETIME, {}, true);
  ASSERT_NE(pack, nullptr);
  EXPECT_EQ(pack->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << pack->reason();
}

TEST(Diag, RefusalsAndOneResultPerCommand) {
  DiagRig rig;
  // Two reads at once: the second is refused diag_busy, the first answers.
  const auto first = diag_payload(rig, v1::DIAGNOSTIC_BLOCK_MC_SETTINGS);
  const auto second = diag_payload(rig, v1::DIAGNOSTIC_BLOCK_BMS_STATUS);
  EXPECT_EQ(rig.service->on_payload(first, rig.bus.now()), Disposition::kStarted);
  // A redelivery while it runs is ignored; its one result follows.
  EXPECT_EQ(rig.service->on_payload(first, rig.bus.now()), Disposition::kDuplicateInProgress);
  const auto* busy = rig.run(second);
  ASSERT_NE(busy, nullptr);
  EXPECT_EQ(reason_code(*busy), "diag_busy") << busy->reason();
  rig.bus.run_for(2s);
  const std::string id = Rig::id_of(first);
  int answers = 0;
  for (const auto& r : rig.results) answers += r.command_id() == id ? 1 : 0;
  EXPECT_EQ(answers, 1);
  ASSERT_NE(rig.result(id), nullptr);
  EXPECT_EQ(rig.result(id)->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED);
  // After it finished, a redelivery gets the stored answer again, and reads nothing.
  const Micros t = rig.bus.now();
  EXPECT_EQ(rig.service->on_payload(first, t), Disposition::kDuplicateAnswered);
  rig.bus.run_for(1s);
  EXPECT_EQ(rig.sender.frames(0x761, 0x33, t), 0u);

  // Malformed: a read mixed with an actuation, an unknown block, lock_model without a lock,
  // last_captured for a block that is not a record, a lock that is not fitted.
  auto c = diag_command(v1::DIAGNOSTIC_BLOCK_MC_SETTINGS, rig.bus.now());
  c.set_action(v1::COMMAND_ACTION_UNLOCK);
  c.set_lock_kind("seat");
  const auto* mixed = rig.run(sign_command(c, rig.key, kKeyId));
  ASSERT_NE(mixed, nullptr);
  EXPECT_EQ(reason_code(*mixed), "malformed") << mixed->reason();
  c = diag_command(v1::DIAGNOSTIC_BLOCK_MC_SETTINGS, rig.bus.now());
  c.mutable_headlight()->set_on(true);
  EXPECT_EQ(reason_code(*rig.run(sign_command(c, rig.key, kKeyId))), "malformed");
  c = diag_command(static_cast<v1::DiagnosticBlock>(99), rig.bus.now());
  EXPECT_EQ(reason_code(*rig.run(sign_command(c, rig.key, kKeyId))), "malformed");
  EXPECT_EQ(reason_code(*rig.run(diag_payload(rig, v1::DIAGNOSTIC_BLOCK_LOCK_MODEL))), "malformed");
  EXPECT_EQ(reason_code(*rig.run(diag_payload(rig, v1::DIAGNOSTIC_BLOCK_MC_SETTINGS, {}, true))),
            "malformed");
  EXPECT_EQ(reason_code(*rig.run(diag_payload(rig, v1::DIAGNOSTIC_BLOCK_LOCK_MODEL, "wheel"))),
            "lock_not_fitted");
  // Refused while an MC action runs (its settings reads must not be mistaken for ours).
  const Micros t2 = rig.bus.now();
  EXPECT_EQ(rig.service->on_payload(rig.mc_payload("speed_limit", "15"), t2),
            Disposition::kStarted);
  const auto* mc_busy = rig.run(diag_payload(rig, v1::DIAGNOSTIC_BLOCK_MC_ASSIST_TUNING));
  ASSERT_NE(mc_busy, nullptr);
  EXPECT_EQ(reason_code(*mc_busy), "mc_busy") << mc_busy->reason();
}

TEST(Diag, ADelegationWithoutTheActionIsRefusedOutOfScope) {
  const auto root = Ed25519PrivateKey::generate();
  const auto console = Ed25519PrivateKey::generate();
  Rig rig(quiet_scenario(), false);
  rig.cfg.command.root_keys["root-1"] = root.public_key().base64();
  rig.make_service();
  rig.bus.run_for(3s);
  auto delegation = [&](std::vector<std::string> actions) {
    v1::Delegation d;
    d.set_serial(actions.size());
    d.set_key_id("console-1");
    const auto pub = console.public_key();
    d.set_public_key(std::string(pub.raw().begin(), pub.raw().end()));
    for (auto& a : actions) d.add_actions(a);
    d.set_all_vehicles(true);
    const Micros now = rig.bus.now();  // the verifier's wall clock in lockstep
    d.set_not_before_us((now - 1h).count());
    d.set_not_after_us((now + 1h).count());
    d.set_issued_at_us((now - 2h).count());
    return sign_delegation(d, root, "root-1");
  };
  const Micros before = rig.bus.now();
  const auto c = diag_command(v1::DIAGNOSTIC_BLOCK_MC_SETTINGS, rig.bus.now());
  const auto* refused =
      rig.run(sign_for_sending(c, console, "console-1", delegation({"lock", "unlock"})).payload);
  ASSERT_NE(refused, nullptr);
  EXPECT_EQ(refused->result(), v1::COMMAND_RESULT_CODE_REJECTED);
  EXPECT_EQ(reason_code(*refused), "out_of_scope") << refused->reason();
  EXPECT_NE(refused->reason().find("diagnostics"), std::string::npos) << refused->reason();
  EXPECT_EQ(rig.sender.frames(0x761, 0x33, before), 0u);  // nothing asked on the bus
  // Granted "diagnostics": read.
  const auto c2 = diag_command(v1::DIAGNOSTIC_BLOCK_MC_SETTINGS, rig.bus.now());
  const auto* read =
      rig.run(sign_for_sending(c2, console, "console-1", delegation({"diagnostics"})).payload);
  ASSERT_NE(read, nullptr);
  EXPECT_EQ(read->result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << read->reason();
  EXPECT_TRUE(read->has_diagnostic());
}

// The schema side: the additions are recorded in the committed snapshot with their numbers, and
// a gateway that predates them (field 14 unknown to it, so ignored) finds no action at all in a
// diagnostic read and refuses it as malformed -- it can never take a read for an actuation.
TEST(DiagSchema, AdditionsAreRecordedAndAnOlderGatewayRefusesAReadAsMalformed) {
  const auto snapshot = fleetgw::testing::load_snapshot(FLEETGW_PROTO_SNAPSHOT);
  const struct {
    const char* message;
    const char* field;
    int number;
  } fields[] = {{"Command", "diagnostic_read", 14},
                {"CommandResult", "diagnostic", 13},
                {"DiagnosticRead", "block", 1},
                {"DiagnosticResult", "messages", 4},
                {"DiagnosticValue", "value_e6", 5}};
  for (const auto& f : fields) {
    const auto* d = fleetgw::testing::find_field(snapshot, f.message, f.field);
    ASSERT_NE(d, nullptr) << f.message << "." << f.field << " missing from the snapshot";
    EXPECT_EQ(d->number(), f.number);
  }
  auto c = diag_command(v1::DIAGNOSTIC_BLOCK_MC_LIFETIME, Micros(1'800'000'000'000'000));
  c.clear_diagnostic_read();  // what an older gateway understands of it
  const auto key = Ed25519PrivateKey::generate();
  VerifierConfig config;
  config.vehicle_id = kVehicle;
  config.trusted_keys[kKeyId] = key.public_key().base64();
  const std::string payload = sign_command(c, key, kKeyId);
  const auto verdict = CommandVerifier(config).authenticate(
      {reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()});
  ASSERT_TRUE(std::holds_alternative<Rejection>(verdict));
  EXPECT_EQ(std::get<Rejection>(verdict).reason, RejectReason::kMalformed);
}

}  // namespace
}  // namespace fleetgw::command::testing
