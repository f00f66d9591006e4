// RAII for a plain rcl program (no rclcpp): the rcl context and a node. An rclcpp program
// does not need these: it hands its own node to ContextNode (contextros/ros/rclcpp.hpp).
//
//   contextros::ros::RclContext context(argc, argv);
//   contextros::ros::RclNode node(context, "localization");
//   contextros::ros::ContextNode follower(node.get());   // follows the Layer manager
#pragma once

#include <memory>
#include <string>

struct rcl_context_s;
struct rcl_node_s;

namespace contextros::ros {

// rcl_init .. rcl_shutdown + rcl_context_fini. Reads ROS_DOMAIN_ID and the discovery
// settings from the environment, as every ROS 2 program does.
class RclContext {
 public:
  RclContext(int argc, const char* const* argv);
  ~RclContext();
  RclContext(const RclContext&) = delete;
  RclContext& operator=(const RclContext&) = delete;
  rcl_context_s& get();
  // False once the context was shut down (rcl_shutdown, e.g. by another owner).
  bool ok();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// rcl_node_init .. rcl_node_fini. Must not outlive its context.
class RclNode {
 public:
  RclNode(RclContext& context, const std::string& name, const std::string& name_space = "");
  ~RclNode();
  RclNode(const RclNode&) = delete;
  RclNode& operator=(const RclNode&) = delete;
  rcl_node_s& get();
  std::string fully_qualified_name() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace contextros::ros
