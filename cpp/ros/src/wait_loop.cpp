// The participant's thread: one wait set (the state, heartbeat and proposal subscriptions
// and a guard condition), each wake-up handed to the protocol adapter.
#include <rcutils/logging_macros.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>

#include "participant_impl.hpp"

namespace contextros::ros {

void Participant::Impl::loop() {
  while (!stopping.load()) {
    try {
      if (!turn()) break;
    } catch (const std::exception& error) {  // nothing may end the thread but stopping
      RCUTILS_LOG_ERROR_NAMED(logger, "participant: %s", error.what());
    } catch (...) {
      RCUTILS_LOG_ERROR_NAMED(logger, "participant: an unknown exception");
    }
  }
}

// One wake-up of the participant's thread; false once it is stopping.
bool Participant::Impl::turn() {
  auto timeout = std::chrono::nanoseconds(0);
  {
    std::lock_guard<std::mutex> lock(mutex);
    timeout = std::max(std::chrono::nanoseconds(0),
                       std::chrono::duration_cast<std::chrono::nanoseconds>(
                           protocol.next_tick() - Clock::now()));
  }
  rcl_wait_set_t* set = wait_set.get();
  if (rcl_wait_set_clear(set) != RCL_RET_OK ||
      rcl_wait_set_add_subscription(set, state_subscription.get(), nullptr) != RCL_RET_OK ||
      rcl_wait_set_add_subscription(set, heartbeat_subscription.get(), nullptr) != RCL_RET_OK ||
      rcl_wait_set_add_subscription(set, proposal_subscription.get(), nullptr) != RCL_RET_OK ||
      rcl_wait_set_add_guard_condition(set, wake.get(), nullptr) != RCL_RET_OK) {
    std::fprintf(stderr, "contextros: participant wait set: %s\n", rcl_get_error_string().str);
    rcl_reset_error();
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    return true;
  }
  const rcl_ret_t waited = rcl_wait(set, timeout.count());
  if (waited != RCL_RET_OK && waited != RCL_RET_TIMEOUT) {
    rcl_reset_error();  // the context is shutting down; the destructor stops us
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    return true;
  }
  if (stopping.load()) {
    return false;
  }
  if (set->subscriptions[0] != nullptr) {
    take_states(state_subscription);
  }
  if (set->subscriptions[1] != nullptr) {
    take_states(heartbeat_subscription);
  }
  if (set->subscriptions[2] != nullptr) {
    take_proposals();
  }
  take_veto_answers();
  notify(settle_deferred());
  if (stopping.load()) {
    return false;
  }
  event([&] { return protocol.tick(Clock::now()); });
  notify_manager_changes();
  return true;
}

}  // namespace contextros::ros
