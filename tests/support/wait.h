// Test support: waiting for a condition instead of sleeping for a fixed time.
//
// Contract: wait_until() evaluates `done` at once and then every `poll` until it returns true
// (result: true) or the deadline passes (result: the last evaluation, made at or after the
// deadline, so a condition that became true just in time still counts). `done` runs on the
// calling thread; anything it needs to make progress (an io_context, another process, a
// thread) must run by itself or inside `done`.
#pragma once

#include <chrono>
#include <thread>
#include <utility>

namespace fleetgw::testing {

template <class Predicate>
bool wait_until(Predicate&& done, std::chrono::steady_clock::time_point deadline,
                std::chrono::milliseconds poll = std::chrono::milliseconds(10)) {
  while (std::chrono::steady_clock::now() < deadline) {
    if (done()) return true;
    std::this_thread::sleep_for(poll);
  }
  return done();
}

template <class Predicate, class Rep, class Period>
bool wait_until(Predicate&& done, std::chrono::duration<Rep, Period> timeout,
                std::chrono::milliseconds poll = std::chrono::milliseconds(10)) {
  return wait_until(std::forward<Predicate>(done),
                    std::chrono::steady_clock::now() +
                        std::chrono::duration_cast<std::chrono::steady_clock::duration>(timeout),
                    poll);
}

}  // namespace fleetgw::testing
