// TransportSender (encode + segment onto a Transport, CRC order from options) and NodeConfig
// validation / the firmware string.
#include <gtest/gtest.h>

#include "fake_bus.h"
#include "gateway/node/transport_sender.h"

namespace fleetgw::node::test {
namespace {

class FakeTransport final : public can::Transport {
 public:
  void start(FrameHandler, HealthHandler) override {}
  bool send(const motinova::CanFrame& frame) override {
    if (refuse_after >= 0 && static_cast<int>(sent.size()) >= refuse_after) return false;
    sent.push_back(frame);
    return true;
  }
  void stop() override {}
  const can::BusHealth& health() const override { return health_; }
  std::string_view name() const override { return "fake"; }

  std::vector<motinova::CanFrame> sent;
  int refuse_after = -1;

 private:
  can::BusHealth health_;
};

std::vector<uint8_t> bytes(const motinova::CanFrame& f) {
  return {f.data.begin(), f.data.begin() + f.len};
}

// Spec test vector T2: IOT -> LOCK 1 UNLOCK, segmented as 8 + 8 + 1 bytes on 0x767.
AppFrame t2() {
  return keyword_frame(0x767, motinova::Mode::kWrite, 0x83, "UNLOCK");
}

TEST(TransportSenderTest, SegmentsOneMessageInOrderOnItsId) {
  FakeTransport transport;
  TransportSender sender(transport, motinova::CrcOrder::kBig);
  ASSERT_TRUE(sender.send(t2()));
  ASSERT_EQ(transport.sent.size(), 3u);
  for (const auto& f : transport.sent) EXPECT_EQ(f.id, 0x767u);
  EXPECT_EQ(bytes(transport.sent[0]),
            (std::vector<uint8_t>{0x55, 0xAA, 0x16, 0x08, 0x83, 0x06, 0x55, 0x4E}));
  EXPECT_EQ(bytes(transport.sent[1]),
            (std::vector<uint8_t>{0x4C, 0x4F, 0x43, 0x4B, 0x84, 0x0B, 0x4B, 0x96}));
  EXPECT_EQ(bytes(transport.sent[2]), (std::vector<uint8_t>{0xF0}));
  EXPECT_EQ(sender.stats().frames_sent, 1u);
  EXPECT_EQ(sender.stats().segments_sent, 3u);
}

TEST(TransportSenderTest, UsesTheConfiguredCrcOrder) {
  FakeTransport transport;
  TransportSender sender(transport, motinova::CrcOrder::kLittle);
  ASSERT_TRUE(sender.send(t2()));
  EXPECT_EQ(bytes(transport.sent[1]),
            (std::vector<uint8_t>{0x4C, 0x4F, 0x43, 0x4B, 0x96, 0x4B, 0x0B, 0x84}));
  sender.set_crc_order(motinova::CrcOrder::kAuto);  // transmit: big-endian
  transport.sent.clear();
  ASSERT_TRUE(sender.send(t2()));
  EXPECT_EQ(transport.sent[1].data[4], 0x84);
}

TEST(TransportSenderTest, RefusedSegmentStopsTheMessageAndReportsFailure) {
  FakeTransport transport;
  transport.refuse_after = 1;
  TransportSender sender(transport, motinova::CrcOrder::kBig);
  EXPECT_FALSE(sender.send(t2()));
  EXPECT_EQ(transport.sent.size(), 1u);
  EXPECT_EQ(sender.stats().frames_failed, 1u);
  EXPECT_EQ(sender.stats().frames_sent, 0u);
}

TEST(NodeConfigTest, DefaultsAreValidAndTheDefaultTableFollowsFittedLocks) {
  NodeConfig cfg;
  EXPECT_NO_THROW(cfg.validate());
  const auto none = cfg.effective_poll_table();
  cfg.fitted_locks = {false, false, false, true, false};
  const auto with_lock4 = cfg.effective_poll_table();
  EXPECT_EQ(with_lock4.size(), none.size() + 2);
  const auto it = std::find_if(with_lock4.begin(), with_lock4.end(),
                               [](const PollEntry& e) { return e.name == "lock4_status"; });
  ASSERT_NE(it, with_lock4.end());
  EXPECT_EQ(it->target_id, 0x76A);
  EXPECT_EQ(it->command, 0xB100);
  EXPECT_EQ(it->answers.at(0), (MessageKey{0x7A0, 0x10}));
}

TEST(NodeConfigTest, BadPollEntriesAreRejectedByName) {
  NodeConfig cfg;
  cfg.poll_table = {PollEntry{"bad_target", 0x720, 0x5000, {{0x720, 0x10}}, 1s}};
  try {
    cfg.validate();
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("bad_target"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("0x720"), std::string::npos) << e.what();
  }
  cfg.poll_table = {PollEntry{"with_data", 0x762, 0x5001, {{0x720, 0x10}}, 1s}};
  EXPECT_THROW(cfg.validate(), std::invalid_argument);
  cfg.poll_table = {PollEntry{"no_answer", 0x762, 0x5000, {}, 1s}};
  EXPECT_THROW(cfg.validate(), std::invalid_argument);
  cfg.poll_table = {PollEntry{"a", 0x762, 0x5000, {{0x720, 0x10}}, 1s},
                    PollEntry{"a", 0x762, 0x5100, {{0x720, 0x11}}, 1s}};
  EXPECT_THROW(cfg.validate(), std::invalid_argument);
  // The facade refuses a bad config before anything reaches the bus.
  Micros clock{0};
  RecordingSender sender(clock);
  EXPECT_THROW(IotNode(cfg, default_options(), sender), std::invalid_argument);
  EXPECT_TRUE(sender.sent.empty());
}

TEST(NodeConfigTest, IdentityMustFitTheModelInfoBlock) {
  NodeConfig cfg;
  cfg.identity.serial = "0123456789ABCDEFG";  // 17 characters
  EXPECT_THROW(cfg.validate(), std::invalid_argument);
  cfg.identity.serial = "SN1";
  cfg.identity.firmware_version = "10.20.30";  // V10.20.30_YYYYMMDD = 18 characters
  EXPECT_THROW(cfg.validate(), std::invalid_argument);
}

TEST(NodeConfigTest, FirmwareStringFormat) {
  EXPECT_EQ(format_firmware("0.1.0", "20250101"), "V0.1.0_20250101");
  EXPECT_THROW(format_firmware("0.1.0", "2025-01-01"), std::invalid_argument);
  EXPECT_THROW(format_firmware("", "20250101"), std::invalid_argument);
  NodeConfig cfg;
  const std::string fw = cfg.identity.firmware();  // build version and date
  EXPECT_EQ(fw.front(), 'V');
  EXPECT_EQ(fw.size(), std::string("V" FLEETGW_VERSION "_YYYYMMDD").size());
}

}  // namespace
}  // namespace fleetgw::node::test
