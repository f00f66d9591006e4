// An rclcpp_lifecycle::LifecycleNode following the Layer manager (follow_manager through its
// NodeBaseInterface), for tests/ros/test_rclcpp.py: /drivers/propeller, announcing the layer
// Flight, whose lifecycle the manager drives through a binding
// (`lifecycle Flight: drivers/propeller active`). Events: `ready`, `applied` (epoch,
// active), `transition` (configure, activate, deactivate... with the state it reached).
#include <contextros/contextros.hpp>
#include <contextros/ros/rclcpp.hpp>
#include <memory>
#include <rclcpp/rclcpp.hpp>
#include <rclcpp_lifecycle/lifecycle_node.hpp>
#include <string>

#include "../json_lines.hpp"

namespace {

using contextros::test_output::emit;
using contextros::test_output::json_list;
using contextros::test_output::json_string;
using CallbackReturn = rclcpp_lifecycle::node_interfaces::LifecycleNodeInterface::CallbackReturn;

class Propeller : public rclcpp_lifecycle::LifecycleNode {
 public:
  Propeller()
      : LifecycleNode("propeller", "drivers"),
        follower_(contextros::ros::follow_manager(*get_node_base_interface())) {}

  CallbackReturn on_configure(const rclcpp_lifecycle::State&) override {
    return reached("configure", "inactive");
  }
  CallbackReturn on_activate(const rclcpp_lifecycle::State& state) override {
    LifecycleNode::on_activate(state);
    return reached("activate", "active");
  }
  CallbackReturn on_deactivate(const rclcpp_lifecycle::State& state) override {
    LifecycleNode::on_deactivate(state);
    return reached("deactivate", "inactive");
  }
  CallbackReturn on_cleanup(const rclcpp_lifecycle::State&) override {
    return reached("cleanup", "unconfigured");
  }

 private:
  static CallbackReturn reached(const std::string& transition, const std::string& state) {
    emit("transition",
         "\"transition\": " + json_string(transition) + ", \"state\": " + json_string(state));
    return CallbackReturn::SUCCESS;
  }
  std::unique_ptr<contextros::ros::ManagerFollower> follower_;
};

}  // namespace

int main(int argc, char** argv) {
  contextros::define_layer({"Flight", {}, {}, {}, ""});
  rclcpp::init(argc, argv);
  contextros::ros::ContextNode::add_listener([](const contextros::ros::LayerState& state) {
    emit("applied", "\"epoch\": " + std::to_string(state.epoch) + ", \"active\": " +
                        json_list(state.active));
  });
  auto node = std::make_shared<Propeller>();
  emit("ready", "\"node\": " + json_string(node->get_fully_qualified_name()));
  rclcpp::spin(node->get_node_base_interface());
  rclcpp::shutdown();
  return 0;
}
