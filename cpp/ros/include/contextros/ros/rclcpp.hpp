// rclcpp nodes follow the Layer manager too: the only rclcpp-specific part of ContextROS's
// C++ participant, kept to this header (built and run against rclcpp by `make test-rclcpp`;
// see docs/cpp.md).
//
//   class Localization : public rclcpp::Node {
//    public:
//     Localization() : Node("localization"), follower_(contextros::ros::follow_manager(*this)) {}
//    private:
//     std::unique_ptr<contextros::ros::ManagerFollower> follower_;  // destroyed before the node
//   };
//
// The participant runs on a thread of its own (it waits on its own rcl wait set), so it
// needs nothing from the node's executor; layered calls made from the node's callbacks see
// either the old configuration or the new one, never a mix. When rclcpp shuts down (Ctrl-C,
// rclcpp::shutdown()), the node leaves in the context's pre-shutdown callback, while it can
// still say so: the manager drops it at once instead of after its liveness bound.
#pragma once

#include <memory>
#include <mutex>
#include <rclcpp/context.hpp>
#include <rclcpp/node.hpp>
#include <rclcpp/node_interfaces/node_base_interface.hpp>
#include <utility>

#include "contextros/ros/participant.hpp"

namespace contextros::ros {

// A ContextNode for an rclcpp node, left when rclcpp's context shuts down or when this is
// destroyed, whichever comes first.
class ManagerFollower {
 public:
  ManagerFollower(rclcpp::node_interfaces::NodeBaseInterface& node, ParticipantOptions options)
      : following_(std::make_shared<Following>()), context_(node.get_context()) {
    following_->node =
        std::make_unique<ContextNode>(*node.get_rcl_node_handle(), std::move(options));
    std::weak_ptr<Following> following = following_;
    on_shutdown_ = context_->add_pre_shutdown_callback([following] {
      if (auto alive = following.lock()) {
        alive->leave();
      }
    });
  }
  ~ManagerFollower() {
    context_->remove_pre_shutdown_callback(on_shutdown_);
    following_->leave();
  }
  ManagerFollower(const ManagerFollower&) = delete;
  ManagerFollower& operator=(const ManagerFollower&) = delete;

  // False once it left (rclcpp shut down).
  bool following() const {
    std::lock_guard<std::mutex> lock(following_->mutex);
    return following_->node != nullptr;
  }

 private:
  struct Following {
    std::mutex mutex;
    std::unique_ptr<ContextNode> node;
    void leave() {
      std::unique_ptr<ContextNode> leaving;
      {
        std::lock_guard<std::mutex> lock(mutex);
        leaving = std::move(node);
      }
    }
  };
  std::shared_ptr<Following> following_;
  rclcpp::Context::SharedPtr context_;
  rclcpp::PreShutdownCallbackHandle on_shutdown_;
};

// Joins the process's shared participant with the rcl node behind `node` (any rclcpp node
// kind: Node, LifecycleNode... through its NodeBaseInterface).
inline std::unique_ptr<ManagerFollower> follow_manager(
    rclcpp::node_interfaces::NodeBaseInterface& node, ParticipantOptions options = {}) {
  return std::make_unique<ManagerFollower>(node, std::move(options));
}

inline std::unique_ptr<ManagerFollower> follow_manager(rclcpp::Node& node,
                                                       ParticipantOptions options = {}) {
  return follow_manager(*node.get_node_base_interface(), std::move(options));
}

}  // namespace contextros::ros
