// rclcpp nodes follow the Layer manager too: the only rclcpp-specific part of ContextROS's
// C++ participant, kept to this header. It needs rclcpp (a system ROS 2: the pip wheels
// have none, so it is not compiled in this repository's own build; see docs/cpp.md).
//
//   class Localization : public rclcpp::Node {
//    public:
//     Localization() : Node("localization"), follower_(contextros::ros::follow_manager(*this)) {}
//    private:
//     std::unique_ptr<contextros::ros::ContextNode> follower_;  // destroyed before the node
//   };
//
// The participant runs on a thread of its own (it waits on its own rcl wait set), so it
// needs nothing from the node's executor; layered calls made from the node's callbacks see
// either the old configuration or the new one, never a mix.
#pragma once

#include <memory>
#include <rclcpp/node.hpp>
#include <utility>

#include "contextros/ros/participant.hpp"

namespace contextros::ros {

// Joins the process's shared participant with the rcl node behind `node` (any rclcpp node
// kind: Node, LifecycleNode... through its NodeBaseInterface).
inline std::unique_ptr<ContextNode> follow_manager(
    rclcpp::node_interfaces::NodeBaseInterface& node, ParticipantOptions options = {}) {
  return std::make_unique<ContextNode>(*node.get_rcl_node_handle(), std::move(options));
}

inline std::unique_ptr<ContextNode> follow_manager(rclcpp::Node& node,
                                                   ParticipantOptions options = {}) {
  return follow_manager(*node.get_node_base_interface(), std::move(options));
}

}  // namespace contextros::ros
