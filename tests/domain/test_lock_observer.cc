// The lock tracker's observer (the geofence judges a lock made on the bike from it): it sees each
// lock event as it is produced, with its new U19 state code and the same cause as the record.
#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

#include "domain_test_util.h"
#include "frames.h"

namespace fleetgw::domain::testing {
namespace {

motinova::AppFrame observed_lock_write(motinova::Node lock, bool lock_it) {
  const int i = motinova::lock_index(lock);
  return writer(motinova::make_can_id(motinova::Node::kIot, lock),
                static_cast<uint8_t>(0x80 + 0x10 * i + (lock_it ? 2 : 3)))
      .frame();
}

TEST(Locks, TheObserverSeesEveryEventWithItsStateCodeAndCause) {
  Harness h(bundled("ride"));
  std::vector<std::pair<std::string, int>> seen;
  h.gateway()->trackers().set_lock_observer([&](const storage::LockEventRow& e, int new_raw) {
    seen.emplace_back(e.kind + " " + e.new_state + " " + e.cause, new_raw);
  });
  h.run_until_offset(5);
  // The rider's key: the frame lock (LOCK 2) opened and closed again, no command involved.
  h.send(observed_lock_write(motinova::Node::kLock2, false));
  h.run_until_offset(15);
  h.send(observed_lock_write(motinova::Node::kLock2, true));
  h.run_until_offset(30);
  const std::vector<std::pair<std::string, int>> want = {{"frame unlocking local", 3},
                                                         {"frame unlocked local", 1},
                                                         {"frame locking local", 4},
                                                         {"frame locked local", 2}};
  EXPECT_EQ(seen, want);
  EXPECT_EQ(seen.size(), h.out.locks.size());  // one call per event stored, no more
}

}  // namespace
}  // namespace fleetgw::domain::testing
