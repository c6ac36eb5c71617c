// TxQueue, the transmit queue shared by the SocketCAN and UDP transports: bounded, in order,
// written from the loop in one go per turn, held while the transport waits for its socket.
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>
#include <asio/io_context.hpp>

#include "gateway/can/tx_queue.h"

namespace fleetgw::can {
namespace {

motinova::CanFrame frame(uint32_t id, uint8_t first_byte = 0) {
  motinova::CanFrame f;
  f.id = id;
  f.len = 1;
  f.data[0] = first_byte;
  return f;
}

struct Drained {
  std::vector<std::vector<uint8_t>> batches;  // first data bytes written per drain call
};

TEST(TxQueue, FramesPushedInOneTurnAreDrainedOnceInOrder) {
  asio::io_context io;
  Drained d;
  TxQueue* q_ptr = nullptr;
  TxQueue q(io, 16, [&] {
    std::vector<uint8_t> batch;
    while (!q_ptr->empty()) {
      batch.push_back(q_ptr->front().data[0]);
      q_ptr->pop();
    }
    d.batches.push_back(batch);
  });
  q_ptr = &q;
  q.start();
  for (uint8_t i = 0; i < 5; ++i) ASSERT_TRUE(q.push(frame(0x761, i)));
  EXPECT_TRUE(d.batches.empty()) << "push() must never write by itself";
  io.run();
  ASSERT_EQ(d.batches.size(), 1u);
  EXPECT_EQ(d.batches[0], (std::vector<uint8_t>{0, 1, 2, 3, 4}));
}

TEST(TxQueue, FullQueueRefusesAndLimitZeroIsAnError) {
  asio::io_context io;
  TxQueue q(io, 2, [] {});
  EXPECT_TRUE(q.push(frame(0x700)));
  EXPECT_TRUE(q.push(frame(0x701)));
  EXPECT_FALSE(q.push(frame(0x702)));
  EXPECT_EQ(q.size(), 2u);
  EXPECT_EQ(q.drop_all(), 2u);
  EXPECT_TRUE(q.empty());
  EXPECT_THROW(TxQueue(io, 0, [] {}), std::invalid_argument);
}

TEST(TxQueue, HeldQueueOnlyQueuesAndStoppedQueueNeverDrains) {
  asio::io_context io;
  int drains = 0;
  TxQueue q(io, 8, [&] { ++drains; });
  q.push(frame(0x700));  // not started: queued, nothing posted
  io.run();
  EXPECT_EQ(drains, 0);
  q.start();
  q.hold();  // the transport waits for its socket
  q.push(frame(0x701));
  io.restart();
  io.run();
  EXPECT_EQ(drains, 0);
  q.release();
  q.push(frame(0x702));
  q.stop();  // posted drain must find the queue stopped
  io.restart();
  io.run();
  EXPECT_EQ(drains, 0);
  EXPECT_EQ(q.size(), 3u);
}

TEST(TxQueue, OnlyClassicStandardFramesAreSendable) {
  EXPECT_TRUE(is_sendable(frame(0x7FF)));
  EXPECT_FALSE(is_sendable(frame(0x800)));
  motinova::CanFrame long_frame = frame(0x700);
  long_frame.len = 9;
  EXPECT_FALSE(is_sendable(long_frame));
}

}  // namespace
}  // namespace fleetgw::can
