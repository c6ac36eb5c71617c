// NodeRegistry: presence, online/offline, fault-word states (UNKNOWN is not "no fault"), model
// info and the latest-message snapshots.
#include <gtest/gtest.h>

#include "fake_bus.h"
#include "gateway/node/node_registry.h"

namespace fleetgw::node::test {
namespace {

struct RecordingObserver : RegistryObserver {
  std::vector<std::pair<Node, Micros>> online, offline;
  std::vector<std::tuple<Node, FaultWordState, FaultWordState>> faults;
  std::vector<std::pair<Node, ModelInfo>> models;
  void on_node_online(Node n, Micros now) override { online.emplace_back(n, now); }
  void on_node_offline(Node n, Micros, Micros now) override { offline.emplace_back(n, now); }
  void on_fault_word(Node n, const FaultWordState& b, const FaultWordState& a, Micros) override {
    faults.emplace_back(n, b, a);
  }
  void on_model_info(Node n, const ModelInfo& info, Micros) override {
    models.emplace_back(n, info);
  }
};

class RegistryTest : public ::testing::Test {
 protected:
  Micros now{10'000'000};
  NodeRegistry registry{RegistryConfig{3s, 2s}};
  RecordingObserver observer;
  void SetUp() override { registry.add_observer(observer); }
  void TearDown() override { registry.remove_observer(observer); }

  void feed(const AppFrame& f) {
    motinova::DecodedMessage msg;
    motinova::decode(f, motinova::Catalogue::standard(), default_options(), msg);
    registry.on_frame(f, msg, now);
  }
  void run_until(Micros until) {
    while (now < until) {
      now += 10ms;
      registry.tick(now);
    }
  }
};

TEST_F(RegistryTest, SilentNodeGoesOfflineAfterTimeoutAndComesBackWhenHeard) {
  const Micros t0 = now;
  feed(peer_fault_word("mc_faults", 0x710, 0));
  EXPECT_TRUE(registry.online(Node::kMc));
  EXPECT_EQ(registry.node(Node::kMc).first_heard, t0);
  ASSERT_EQ(observer.online.size(), 1u);

  run_until(t0 + 2990ms);
  EXPECT_TRUE(registry.online(Node::kMc)) << "still within the 3 s offline timeout";
  EXPECT_TRUE(observer.offline.empty());
  run_until(t0 + 3s);
  EXPECT_FALSE(registry.online(Node::kMc));
  ASSERT_EQ(observer.offline.size(), 1u);
  EXPECT_EQ(observer.offline[0], std::make_pair(Node::kMc, t0 + 3s));
  run_until(t0 + 6s);
  EXPECT_EQ(observer.offline.size(), 1u) << "offline is reported once";

  feed(peer_fault_word("mc_faults", 0x710, 0));
  EXPECT_TRUE(registry.online(Node::kMc));
  ASSERT_EQ(observer.online.size(), 2u);
  EXPECT_EQ(observer.online[1].second, t0 + 6s);
  EXPECT_EQ(registry.node(Node::kMc).first_heard, t0) << "first_heard survives an outage";
  EXPECT_TRUE(registry.node(Node::kMc).present);
  EXPECT_FALSE(registry.node(Node::kBms).present);
}

TEST_F(RegistryTest, StaleFaultWordIsUnknownNotNoFault) {
  const Micros t0 = now;
  EXPECT_EQ(registry.fault_word(Node::kBms, now).state, FaultState::kUnknown) << "never heard";
  feed(peer_fault_word("bms_faults", 0x720, 0));
  EXPECT_EQ(registry.fault_word(Node::kBms, now).state, FaultState::kOk);

  run_until(t0 + 1990ms);
  EXPECT_EQ(registry.node(Node::kBms).faults.state, FaultState::kOk);
  run_until(t0 + 2s);
  const FaultWordState stale = registry.node(Node::kBms).faults;
  EXPECT_EQ(stale.state, FaultState::kUnknown);
  ASSERT_TRUE(stale.raw.has_value());
  EXPECT_EQ(*stale.raw, 0u) << "the last word is kept for context";
  ASSERT_EQ(observer.faults.size(), 2u);  // unknown -> ok, ok -> unknown
  EXPECT_EQ(std::get<1>(observer.faults[1]).state, FaultState::kOk);
  EXPECT_EQ(std::get<2>(observer.faults[1]).state, FaultState::kUnknown);

  // The node is still online (it could be sending other frames): staleness is per fault word.
  feed(bms_status());
  run_until(t0 + 3s);
  EXPECT_EQ(registry.fault_word(Node::kBms, now).state, FaultState::kUnknown);
}

TEST_F(RegistryTest, FaultWordChangesAreReportedOnceEach) {
  feed(peer_fault_word("mc_faults", 0x710, 0));
  feed(peer_fault_word("mc_faults", 0x710, 0));  // repeat: no notification
  feed(peer_fault_word("mc_faults", 0x710, 0x0020));
  feed(peer_fault_word("mc_faults", 0x710, 0x0020));
  feed(peer_fault_word("mc_faults", 0x710, 0x0060));  // still faulty, other bits: reported
  ASSERT_EQ(observer.faults.size(), 3u);
  const FaultWordState now_state = registry.node(Node::kMc).faults;
  EXPECT_EQ(now_state.state, FaultState::kFaulty);
  EXPECT_EQ(now_state.raw, 0x0060u);
  EXPECT_EQ(std::get<2>(observer.faults[2]).raw, 0x0060u);
}

TEST_F(RegistryTest, ModelInfoAndLatestSnapshotAreValueCopies) {
  {
    const AppFrame f = peer_model_info(0x730, "OBC-X1", "OBC123");
    feed(f);
  }  // the frame is gone; the registry must not hold views into it
  const NodeState& obc = registry.node(Node::kObc);
  ASSERT_TRUE(obc.model.has_value());
  EXPECT_EQ(obc.model->model, "OBC-X1");
  EXPECT_EQ(obc.model->serial, "OBC123");
  EXPECT_EQ(obc.model->fw, "V1.2.3_20240501");
  ASSERT_EQ(observer.models.size(), 1u);
  const MessageSnapshot* snap = obc.find(0x730, 0x11);
  ASSERT_NE(snap, nullptr);
  EXPECT_EQ(snap->name, "device_info");
  EXPECT_EQ(snap->frame.data.size(), 64u);
  EXPECT_EQ(obc.find("device_info"), snap);

  now += 1s;
  feed(peer_model_info(0x730, "OBC-X1", "OBC123"));
  EXPECT_EQ(observer.models.size(), 1u) << "unchanged model info is not re-announced";
  feed(peer_model_info(0x730, "OBC-X2", "OBC999"));
  EXPECT_EQ(observer.models.size(), 2u);
}

TEST_F(RegistryTest, UnknownAndCdlNodesAreNoted) {
  feed(motinova::make_frame(0x751, motinova::Mode::kRead, 0x12, std::vector<uint8_t>{}));
  feed(motinova::make_frame(0x7C0, motinova::Mode::kReport, 0x01, std::vector<uint8_t>{1, 2}));
  const auto present = registry.present_nodes();
  ASSERT_EQ(present.size(), 2u);
  EXPECT_EQ(present[0], Node::kCdl);
  EXPECT_EQ(static_cast<int>(present[1]), 0xC);
  const MessageSnapshot* unknown = registry.node(static_cast<Node>(0xC)).find(0x7C0, 0x01);
  ASSERT_NE(unknown, nullptr);
  EXPECT_EQ(unknown->name, "unknown");
}

}  // namespace
}  // namespace fleetgw::node::test
