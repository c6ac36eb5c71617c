// Issue 24, finding 4 ("commands vanish without a result"), at the uplink's queue: a real
// mosquitto, the real Uplink with the command service's authenticator (as the pipeline wires
// it), the CommandService on the simulated bike. The owner's thread does not take commands
// until Paho has sorted the whole burst, so the queue is full by construction (no timing):
//  * every authenticated command the queue cannot take is answered `busy` with its id, and a
//    busy command sent again runs;
//  * unauthenticated payloads have their own small budget and never take an authenticated
//    command's place; what reaches the owner's thread of a junk flood is bounded by a rate;
//  * every drop is counted by class.
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <map>
#include <memory>

#include "gateway/runtime/store_outbox.h"
#include "gateway/uplink/uplink.h"
#include "motinova/catalogue.h"
#include "tests/command/burst_client.h"
#include "tests/command/command_test_util.h"

namespace fleetgw::command::testing {
namespace {

// The pipeline's adapter (gateway/runtime/pipeline.cc): the service's signature check, run on
// Paho's thread.
uplink::CommandAuthenticator triage_with(PayloadAuthenticator auth) {
  return [auth = std::move(auth)](std::string_view payload) {
    auto a = auth({reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()});
    return uplink::CommandTriage{a.authenticated, std::move(a.command_id),
                                 std::move(a.command_sha256)};
  };
}

// The gateway side: the rig's bus follows the wall clock; the uplink's commands go to the
// service only when `take` is set, so a test can let a burst pile up first.
class QueueGateway {
 public:
  explicit QueueGateway(const std::string& broker_uri) : rig(live()), outbox(*rig.store) {
    uplink::UplinkConfig c;
    c.broker_uri = broker_uri;
    c.vehicle_id = kVehicle;
    c.firmware_version = "test";
    c.reconnect_min = 200ms;
    c.reconnect_max = 1000ms;
    link = std::make_unique<uplink::Uplink>(c, outbox);
    link->set_command_authenticator(triage_with(rig.service->authenticator()));
    link->start(wall_now());
  }
  ~QueueGateway() { link->stop(wall_now(), 2s); }

  static sim::Scenario live() {
    auto sc = quiet_scenario();
    sc.start = wall_now();
    return sc;
  }

  void step() {
    const Micros now = wall_now();
    if (now > rig.bus.now()) rig.bus.run_until(now);
    link->poll(now);
    if (take) {
      for (const auto& payload : link->take_commands()) rig.service->on_payload(payload, now);
      for (const auto& b : link->take_busy_commands()) {
        EXPECT_EQ(rig.service->answer_busy(b.command_id, b.command_sha256, now), Disposition::kBusy)
            << b.command_id;
      }
    }
    link->wait_for_events(2ms);
  }
  template <class Pred>
  bool step_until(Pred done, std::chrono::seconds limit) {
    const auto end = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < end) {
      step();
      if (done()) return true;
    }
    return done();
  }
  // Connected, subscribed to cmd (a probe payload came back as a counted drop) and the seat
  // lock heard on the bus.
  bool ready(BurstClient& backend) {
    if (!step_until([&] { return link->state() == uplink::UplinkState::kConnected; }, 20s)) {
      return false;
    }
    // Undecodable: dropped and counted, never answered; sent again (every 250 ms) until the
    // subscription is up. A probe still under way may arrive later: tests count undecodable
    // drops with that in mind.
    auto last_probe = std::chrono::steady_clock::time_point{};
    return step_until(
        [&] {
          const auto now = std::chrono::steady_clock::now();
          if (link->stats().commands_dropped_undecodable == 0 && now - last_probe > 250ms) {
            backend.publish(
                {"\x0a\x05"
                 "ab"});
            last_probe = now;
          }
          return link->stats().commands_dropped_undecodable > 0 &&
                 rig.core->node().registry().online(motinova::lock_node(0));
        },
        20s);
  }
  // Command payloads the uplink has sorted (probes left out).
  std::uint64_t accounted() const {
    const auto s = link->stats();
    return s.commands_received + s.commands_busy + s.commands_dropped -
           s.commands_dropped_undecodable;
  }

  Rig rig;
  runtime::StoreOutbox outbox;
  std::unique_ptr<uplink::Uplink> link;
  bool take = false;
};

SentCommand signed_seat(Rig& rig, const std::string& id, std::string_view action) {
  const Micros now = wall_now();
  return sign_for_sending(*make_command(kVehicle, "seat", action, now, now + 60s, id), rig.key,
                          kKeyId);
}

// Signed seat commands, by id in the order sent.
struct Burst {
  std::vector<std::string> ids;
  std::map<std::string, SentCommand> sent;
};

// What every test starts from: a real mosquitto, the gateway side connected and subscribed with
// the seat lock heard (QueueGateway::ready), the backend's client, and how many payloads the
// uplink had sorted by then (the probes).
class CommandMqttBurst : public ::testing::Test {
 protected:
  void SetUp() override {
    broker_.start();
    started_ = std::chrono::steady_clock::now();  // before the uplink's budgets start
    gateway_ = std::make_unique<QueueGateway>(broker_.uri());
    backend_ = std::make_unique<BurstClient>(broker_.uri(), kVehicle);
    ASSERT_TRUE(gateway_->ready(*backend_)) << broker_.log();
    before_ = gateway_->accounted();
  }

  // `count` signed seat commands "<prefix><i>" doing action(i), published back to back.
  Burst publish_burst(const std::string& prefix, int count,
                      const std::function<std::string_view(int)>& action) {
    Burst b;
    std::vector<std::string> payloads;
    for (int i = 0; i < count; ++i) {
      b.ids.push_back(prefix + std::to_string(i));
      b.sent[b.ids.back()] = signed_seat(gateway_->rig, b.ids.back(), action(i));
      payloads.push_back(b.sent[b.ids.back()].payload);
    }
    backend_->publish(payloads);
    return b;
  }
  // Waits until the uplink has sorted `count` payloads since the set-up; the owner's thread
  // takes none of them until `take` is set.
  bool sorted(std::uint64_t count) {
    return gateway_->step_until([&] { return gateway_->accounted() - before_ == count; }, 20s);
  }
  std::uint64_t sorted_so_far() const { return gateway_->accounted() - before_; }

  fleetgw::testing::MosquittoBroker broker_;
  std::chrono::steady_clock::time_point started_;
  std::unique_ptr<QueueGateway> gateway_;
  std::unique_ptr<BurstClient> backend_;
  std::uint64_t before_ = 0;
};

TEST_F(CommandMqttBurst, EveryAuthenticatedCommandTheQueueCannotTakeIsAnsweredBusy) {
  QueueGateway& gw = *gateway_;
  BurstClient& backend = *backend_;
  // 40 signed commands on the seat lock, distinct ids: unlock, lock, unlock, ...
  constexpr int kBurst = 40;
  Burst burst =
      publish_burst("burst-", kBurst, [](int i) { return i % 2 == 0 ? "unlock" : "lock"; });
  const auto& ids = burst.ids;
  auto& sent = burst.sent;
  ASSERT_TRUE(sorted(kBurst)) << sorted_so_far();
  const auto s = gw.link->stats();
  EXPECT_EQ(s.commands_received, 16u) << "max_queued_commands wait for the owner";
  EXPECT_EQ(s.commands_busy, kBurst - 16u);
  EXPECT_EQ(s.commands_dropped, s.commands_dropped_undecodable) << "nothing but probes dropped";
  EXPECT_EQ(s.commands_dropped_queue_full, 0u);

  gw.take = true;
  ASSERT_TRUE(gw.step_until([&] { return backend.answers(sent).size() == sent.size(); }, 20s))
      << backend.answers(sent).size() << " of " << sent.size() << " answered";
  // Exactly one answer per command, each definite; the queue-full ones say `busy`.
  std::size_t busy = 0;
  for (const auto& [id, answers] : backend.answers(sent)) {
    ASSERT_EQ(answers.size(), 1u) << id;
    const std::string code = reason_code_of(answers[0]);
    if (code == "busy") ++busy;
    EXPECT_TRUE(answers[0].result() == v1::COMMAND_RESULT_CODE_SUCCEEDED || code == "busy" ||
                code == "lock_busy")
        << id << ": " << answers[0].ShortDebugString();
  }
  EXPECT_EQ(busy, kBurst - 16u);
  ASSERT_TRUE(
      gw.step_until([&] { return gw.rig.lock_state(0) == sim::LockState::kUnlocked; }, 10s));

  // A busy command sent again runs normally: `busy` did not mark its id as used.
  const std::string again = ids.back();  // a "lock", answered busy above
  ASSERT_EQ(reason_code_of(backend.answers(sent)[again][0]), "busy");
  backend.publish({sent[again].payload});
  ASSERT_TRUE(gw.step_until([&] { return backend.answers(sent)[again].size() == 2; }, 20s));
  const auto second = backend.answers(sent)[again][1];
  EXPECT_EQ(second.result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << second.ShortDebugString();
  EXPECT_EQ(gw.rig.lock_state(0), sim::LockState::kLocked);
  EXPECT_EQ(gw.rig.sender.lock_writes(), 2u) << "the first unlock and the re-sent lock only";
}

// The service stops with a burst still in the uplink's queue (Pipeline::finish answers what
// the uplink holds, before, during and after its drain, with these two calls): every command
// gets exactly one result -- shutting_down for the 16 queued, busy for the 24 busy notices --
// nothing runs on the bus, and a command answered shutting_down runs when sent again.
TEST_F(CommandMqttBurst, CommandsStillQueuedWhenTheGatewayStopsAreAnsweredShuttingDown) {
  QueueGateway& gw = *gateway_;
  BurstClient& backend = *backend_;
  constexpr int kBurst = 40;
  Burst burst = publish_burst("stop-", kBurst, [](int) { return "unlock"; });
  const auto& ids = burst.ids;
  auto& sent = burst.sent;
  ASSERT_TRUE(sorted(kBurst)) << sorted_so_far();

  // The stop: what the uplink holds is answered, nothing is run.
  const Micros now = wall_now();
  for (const auto& payload : gw.link->take_commands()) {
    EXPECT_EQ(gw.rig.service->answer_stopping(
                  {reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()}, now),
              Disposition::kBusy);
  }
  for (const auto& b : gw.link->take_busy_commands()) {
    gw.rig.service->answer_busy(b.command_id, b.command_sha256, now);
  }
  ASSERT_TRUE(gw.step_until([&] { return backend.answers(sent).size() == sent.size(); }, 20s))
      << backend.answers(sent).size() << " of " << sent.size() << " answered";
  std::map<std::string, int> by_code;
  for (const auto& [id, answers] : backend.answers(sent)) {
    ASSERT_EQ(answers.size(), 1u) << id;
    EXPECT_EQ(answers[0].result(), v1::COMMAND_RESULT_CODE_REJECTED) << id;
    ++by_code[reason_code_of(answers[0])];
  }
  EXPECT_EQ(by_code["shutting_down"], 16);
  EXPECT_EQ(by_code["busy"], kBurst - 16);
  EXPECT_EQ(gw.rig.sender.lock_writes(), 0u) << "nothing runs at a stop";
  EXPECT_EQ(gw.rig.lock_state(0), sim::LockState::kLocked);

  // Not recorded as used: sent again (after the restart), it runs.
  const std::string again = ids.front();
  ASSERT_EQ(reason_code_of(backend.answers(sent)[again][0]), "shutting_down");
  gw.take = true;
  backend.publish({sent[again].payload});
  ASSERT_TRUE(gw.step_until([&] { return backend.answers(sent)[again].size() == 2; }, 20s));
  const auto second = backend.answers(sent)[again][1];
  EXPECT_EQ(second.result(), v1::COMMAND_RESULT_CODE_SUCCEEDED) << second.ShortDebugString();
  EXPECT_TRUE(
      gw.step_until([&] { return gw.rig.lock_state(0) == sim::LockState::kUnlocked; }, 10s));
}

TEST_F(CommandMqttBurst, JunkNeverTakesAnAuthenticatedCommandsPlaceAndEveryDropIsCounted) {
  QueueGateway& gw = *gateway_;
  BurstClient& backend = *backend_;

  // 100 well-formed commands under the trusted key id with zeroed signatures, then the genuine
  // one, all before the owner takes anything.
  std::vector<std::string> payloads;
  for (int i = 0; i < 100; ++i) {
    const Micros now = wall_now();
    payloads.push_back(junk_command(
        *make_command(kVehicle, "seat", "unlock", now, now + 60s, "junk-" + std::to_string(i)),
        kKeyId));
  }
  std::map<std::string, SentCommand> genuine{{"genuine", signed_seat(gw.rig, "genuine", "unlock")}};
  payloads.push_back(genuine["genuine"].payload);
  backend.publish(payloads);
  ASSERT_TRUE(sorted(101)) << sorted_so_far();
  auto s = gw.link->stats();
  EXPECT_EQ(s.commands_unauthenticated, 4u) << "the unauthenticated lane's queue";
  EXPECT_EQ(s.commands_received, 5u) << "4 unauthenticated + the genuine command";
  EXPECT_EQ(s.commands_dropped_unauthenticated, 96u);
  EXPECT_EQ(s.commands_busy, 0u);
  EXPECT_EQ(s.commands_dropped_queue_full, 0u);

  gw.take = true;
  ASSERT_TRUE(gw.step_until([&] { return backend.answers(genuine).size() == 1; }, 20s));
  ASSERT_TRUE(
      gw.step_until([&] { return gw.rig.lock_state(0) == sim::LockState::kUnlocked; }, 10s));
  const auto answers = backend.answers(genuine)["genuine"];
  ASSERT_EQ(answers.size(), 1u);
  EXPECT_EQ(answers[0].result(), v1::COMMAND_RESULT_CODE_SUCCEEDED)
      << answers[0].ShortDebugString();

  // A flood while the owner takes all it is given: what reaches its thread is bounded by the
  // unauthenticated budget (10 at once, 30 per minute), whatever the flood's size.
  const std::uint64_t flood_base = gw.accounted();
  payloads.resize(100);
  std::vector<std::string> flood = payloads;
  flood.insert(flood.end(), payloads.begin(), payloads.end());
  backend.publish(flood);
  ASSERT_TRUE(gw.step_until([&] { return gw.accounted() - flood_base == 200; }, 20s));
  s = gw.link->stats();
  const double minutes =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count() / 60;
  EXPECT_LE(static_cast<double>(s.commands_unauthenticated), 10 + 30 * minutes);
  EXPECT_EQ(s.commands_unauthenticated + s.commands_dropped_unauthenticated, 300u);

  // Oversized and undecodable payloads: counted by class, never handed over (the probes of
  // ready() were undecodable already).
  const auto probes = gw.link->stats().commands_dropped_undecodable;
  backend.publish({std::string(5000, 'x'),
                   "\x0a\x05"
                   "ab"});
  ASSERT_TRUE(gw.step_until(
      [&] {
        const auto t = gw.link->stats();
        return t.commands_dropped_oversized == 1 && t.commands_dropped_undecodable > probes;
      },
      20s));
  s = gw.link->stats();
  EXPECT_EQ(s.commands_dropped, s.commands_dropped_oversized + s.commands_dropped_undecodable +
                                    s.commands_dropped_unauthenticated +
                                    s.commands_dropped_queue_full);
  EXPECT_EQ(s.commands_dropped_queue_full, 0u);
  EXPECT_EQ(gw.rig.sender.lock_writes(), 1u) << "the genuine unlock only";
}

}  // namespace
}  // namespace fleetgw::command::testing
