// SocketCAN on the build host. The project's machines run a kernel without CAN, so what can be
// tested here is that construction fails cleanly with a clear message. The real SocketCAN code
// path is tested in a VM: tests/vm/test_socketcan_vm.cc.
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <string>

#include <gtest/gtest.h>
#include <asio/io_context.hpp>

#include "gateway/can/socketcan_transport.h"
#include "gateway/can/timestamp_guard.h"

namespace fleetgw::can {
namespace {

bool kernel_has_socketcan() {
  const int fd = ::socket(PF_CAN, SOCK_RAW, 1 /*CAN_RAW*/);
  if (fd >= 0) {
    ::close(fd);
    return true;
  }
  return errno != EAFNOSUPPORT;
}

TEST(SocketCanHost, WithoutKernelSupportConstructionFailsWithClearError) {
  if (kernel_has_socketcan()) {
    GTEST_SKIP() << "this kernel supports SocketCAN; the no-support path cannot be tested here";
  }
  asio::io_context io;
  SocketCanOptions o;
  o.interface = "can0";
  try {
    SocketCanTransport t(io, o);
    FAIL() << "construction succeeded without SocketCAN";
  } catch (const SocketCanError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("this kernel has no SocketCAN support"), std::string::npos) << what;
    EXPECT_NE(what.find("EAFNOSUPPORT"), std::string::npos) << what;
  }
}

TEST(SocketCanHost, InvalidOptionsAreRejectedBeforeTouchingTheKernel) {
  asio::io_context io;
  SocketCanOptions o;
  o.interface = "";
  EXPECT_THROW(SocketCanTransport(io, o), SocketCanError);
  o.interface = "a_name_longer_than_ifnamsiz";
  try {
    SocketCanTransport t(io, o);
    FAIL();
  } catch (const SocketCanError& e) {
    EXPECT_NE(std::string(e.what()).find("invalid CAN interface name"), std::string::npos);
  }
  o.interface = "can0";
  o.tx_queue_limit = 0;
  EXPECT_THROW(SocketCanTransport(io, o), SocketCanError);
}

TEST(SocketCanHost, ControllerStateNames) {
  EXPECT_EQ(controller_state_name(ControllerState::kUp), "up");
  EXPECT_EQ(controller_state_name(ControllerState::kBusOff), "bus_off");
  EXPECT_EQ(controller_state_name(ControllerState::kDown), "down");
}

TEST(TimestampGuard, ClampsSmallRegressionsPassesClockSteps) {
  using motinova::Micros;
  TimestampGuard g(Micros{1'000'000});
  EXPECT_EQ(g.apply(Micros{10'000'000}), Micros{10'000'000});
  EXPECT_EQ(g.apply(Micros{10'020'000}), Micros{10'020'000});
  // A frame stamped 95 ms "earlier" (read-time vs arrival stamping): held at the last value.
  EXPECT_EQ(g.apply(Micros{9'925'000}), Micros{10'020'000});
  EXPECT_EQ(g.clamped(), 1U);
  EXPECT_EQ(g.apply(Micros{10'040'000}), Micros{10'040'000});
  // The wall clock set back an hour: followed, not frozen for an hour.
  const Micros stepped{10'040'000 - 3'600'000'000LL};
  EXPECT_EQ(g.apply(stepped), stepped);
  EXPECT_EQ(g.clock_steps(), 1U);
  g.reset();
  EXPECT_EQ(g.apply(Micros{5}), Micros{5});
  EXPECT_EQ(g.clamped(), 1U);
}

}  // namespace
}  // namespace fleetgw::can
