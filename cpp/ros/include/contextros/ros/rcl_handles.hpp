// RAII owners of rcl handles, for the participant and for plain rcl programs (the example
// node): each is initialised in its constructor (throwing ParticipantError with rcl's
// message) and finalised in its destructor. Not copyable, not movable: they live as members
// of their owner, declared after the node they use. With a message type, e.g.
//   RclSubscription imu(node, type_support<sensor_msgs::msg::Imu>(), "imu", qos);
//   sensor_msgs::msg::Imu message; while (imu.take(message)) { ... }
#pragma once

#include <rcl/error_handling.h>
#include <rcl/rcl.h>

#include <chrono>
#include <rosidl_typesupport_cpp/message_type_support.hpp>
#include <string>

#include "contextros/ros/participant.hpp"

namespace contextros::ros {

// The C++ type support of a generated message type.
template <class Message>
const rosidl_message_type_support_t* type_support() {
  return rosidl_typesupport_cpp::get_message_type_support_handle<Message>();
}

// A QoS profile: the default (reliable, volatile) with this depth.
inline rmw_qos_profile_t keep_last(std::size_t depth) {
  rmw_qos_profile_t qos = rmw_qos_profile_default;
  qos.depth = depth;
  return qos;
}

namespace detail {

[[noreturn]] inline void fail(const std::string& what) {
  std::string message = what + ": " + rcl_get_error_string().str;
  rcl_reset_error();
  throw ParticipantError(message);
}

inline void check(rcl_ret_t ret, const char* what) {
  if (ret != RCL_RET_OK) {
    fail(what);
  }
}

// For finalisers and calls whose failure leaves nothing to do: forget rcl's error state.
inline void ignore_failure(rcl_ret_t ret) {
  if (ret != RCL_RET_OK) {
    rcl_reset_error();
  }
}

class NonCopyable {
 public:
  NonCopyable() = default;
  NonCopyable(const NonCopyable&) = delete;
  NonCopyable& operator=(const NonCopyable&) = delete;
};

}  // namespace detail

class RclPublisher : detail::NonCopyable {
 public:
  RclPublisher(rcl_node_t& node, const rosidl_message_type_support_t* type, const char* topic,
            const rmw_qos_profile_t& qos)
      : node_(node) {
    rcl_publisher_options_t options = rcl_publisher_get_default_options();
    options.qos = qos;
    detail::check(rcl_publisher_init(&handle_, &node_, type, topic, &options),
          std::string("cannot create a publisher on ").append(topic).c_str());
  }
  ~RclPublisher() {
    detail::ignore_failure(rcl_publisher_fini(&handle_, &node_));
  }
  rcl_publisher_t* get() { return &handle_; }
  // Publishes a message of the type it was made for; false if rcl failed (logged by rcl).
  template <class Message>
  bool publish(const Message& message) {
    if (rcl_publish(&handle_, &message, nullptr) == RCL_RET_OK) {
      return true;
    }
    rcl_reset_error();
    return false;
  }

 private:
  rcl_node_t& node_;
  rcl_publisher_t handle_ = rcl_get_zero_initialized_publisher();
};

class RclSubscription : detail::NonCopyable {
 public:
  RclSubscription(rcl_node_t& node, const rosidl_message_type_support_t* type, const char* topic,
               const rmw_qos_profile_t& qos)
      : node_(node) {
    rcl_subscription_options_t options = rcl_subscription_get_default_options();
    options.qos = qos;
    detail::check(rcl_subscription_init(&handle_, &node_, type, topic, &options),
          std::string("cannot subscribe to ").append(topic).c_str());
  }
  ~RclSubscription() {
    detail::ignore_failure(rcl_subscription_fini(&handle_, &node_));
  }
  rcl_subscription_t* get() { return &handle_; }
  // Takes the next message waiting, if any (of the type it was made for).
  template <class Message>
  bool take(Message& message) {
    if (rcl_take(&handle_, &message, nullptr, nullptr) == RCL_RET_OK) {
      return true;
    }
    rcl_reset_error();  // RCL_RET_SUBSCRIPTION_TAKE_FAILED: nothing waiting
    return false;
  }

 private:
  rcl_node_t& node_;
  rcl_subscription_t handle_ = rcl_get_zero_initialized_subscription();
};

// Wakes the participant's wait from another thread (rcl_trigger_guard_condition is
// thread-safe).
class RclGuardCondition : detail::NonCopyable {
 public:
  explicit RclGuardCondition(rcl_context_t* context) {
    detail::check(rcl_guard_condition_init(&handle_, context, rcl_guard_condition_get_default_options()),
          "cannot create a guard condition");
  }
  ~RclGuardCondition() {
    detail::ignore_failure(rcl_guard_condition_fini(&handle_));
  }
  rcl_guard_condition_t* get() { return &handle_; }
  void trigger() { detail::ignore_failure(rcl_trigger_guard_condition(&handle_)); }

 private:
  rcl_guard_condition_t handle_ = rcl_get_zero_initialized_guard_condition();
};

class RclWaitSet : detail::NonCopyable {
 public:
  RclWaitSet(rcl_context_t* context, std::size_t subscriptions, std::size_t guard_conditions) {
    detail::check(rcl_wait_set_init(&handle_, subscriptions, guard_conditions, 0, 0, 0, 0, context,
                            rcl_get_default_allocator()),
          "cannot create a wait set");
  }
  ~RclWaitSet() {
    detail::ignore_failure(rcl_wait_set_fini(&handle_));
  }
  rcl_wait_set_t* get() { return &handle_; }

 private:
  rcl_wait_set_t handle_ = rcl_get_zero_initialized_wait_set();
};

}  // namespace contextros::ros
