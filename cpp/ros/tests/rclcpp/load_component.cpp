// Loads a component into an rclcpp_components container over its LoadNode service, as
// `ros2 component load` does, for tests/ros/test_rclcpp.py.
// usage: load_component CONTAINER PACKAGE PLUGIN; prints `loaded` (success, name, error).
#include <chrono>
#include <composition_interfaces/srv/load_node.hpp>
#include <memory>
#include <rclcpp/rclcpp.hpp>
#include <string>

#include "../json_lines.hpp"

int main(int argc, char** argv) {
  using contextros::test_output::emit;
  using contextros::test_output::json_string;
  using LoadNode = composition_interfaces::srv::LoadNode;
  const auto arguments = rclcpp::init_and_remove_ros_arguments(argc, argv);
  if (arguments.size() != 4) {
    std::fprintf(stderr, "usage: load_component CONTAINER PACKAGE PLUGIN\n");
    return 2;
  }
  auto node = std::make_shared<rclcpp::Node>("component_loader");
  auto client = node->create_client<LoadNode>(arguments[1] + "/_container/load_node");
  if (!client->wait_for_service(std::chrono::seconds(15))) {
    emit("loaded", "\"success\": false, \"error\": \"no container\"");
    return 1;
  }
  auto request = std::make_shared<LoadNode::Request>();
  request->package_name = arguments[2];
  request->plugin_name = arguments[3];
  auto future = client->async_send_request(request);
  if (rclcpp::spin_until_future_complete(node, future, std::chrono::seconds(15)) !=
      rclcpp::FutureReturnCode::SUCCESS) {
    emit("loaded", "\"success\": false, \"error\": \"no answer\"");
    return 1;
  }
  const auto response = future.get();
  emit("loaded", std::string("\"success\": ") + (response->success ? "true" : "false") +
                     ", \"name\": " + json_string(response->full_node_name) +
                     ", \"error\": " + json_string(response->error_message));
  rclcpp::shutdown();
  return response->success ? 0 : 1;
}
