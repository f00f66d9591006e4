// Two rclcpp components following the Layer manager, for tests/ros/test_rclcpp.py: loaded
// into one rclcpp_components container, the process has one participant (the second node is
// hosted by the first's), and one switch rewires both. Wheels announces Slow (its layered
// `drive()`: "normal", "careful" under Slow); Lights announces Night (`light()`: "off", "on"
// under Night). Each prints `applied` (node, epoch, active, behaviour) after every state.
#include <contextros/contextros.hpp>
#include <contextros/ros/rclcpp.hpp>
#include <memory>
#include <rclcpp/rclcpp.hpp>
#include <rclcpp_components/register_node_macro.hpp>
#include <string>
#include <vector>

#include "../json_lines.hpp"

namespace contextros_rclcpp_tests {

using contextros::test_output::emit;
using contextros::test_output::json_list;
using contextros::test_output::json_string;
using Behaviour = std::string();
using Proceed = contextros::ProceedOf<Behaviour>;

bool define_layers() {
  contextros::define_layer({"Slow", {}, {}, {}, ""});
  contextros::define_layer({"Night", {}, {}, {}, ""});
  return true;
}
const bool layers_defined = define_layers();  // before the layered functions below

contextros::LayeredOf<Behaviour> drive{
    "drive", [](Proceed) -> std::string { return "normal"; },
    {{"Slow", [](Proceed) -> std::string { return "careful"; }}}};
contextros::LayeredOf<Behaviour> light{
    "light", [](Proceed) -> std::string { return "off"; },
    {{"Night", [](Proceed) -> std::string { return "on"; }}}};

// A component node announcing `layer`, printing what `behaviour` returns after each state.
class Component : public rclcpp::Node {
 protected:
  Component(const std::string& name, const rclcpp::NodeOptions& options, const char* layer,
            contextros::LayeredOf<Behaviour>& behaviour)
      : Node(name, options),
        follower_(contextros::ros::follow_manager(*this, announcing(layer))) {
    (void)layers_defined;
    const std::string node = get_fully_qualified_name();
    contextros::ros::ContextNode::add_listener(
        [node, &behaviour](const contextros::ros::LayerState& state) {
          emit("applied", "\"node\": " + json_string(node) + ", \"epoch\": " +
                              std::to_string(state.epoch) + ", \"active\": " +
                              json_list(state.active) + ", \"behaviour\": " +
                              json_string(behaviour.invoke(nullptr)));
        });
    emit("ready", "\"node\": " + json_string(node) + ", \"carrier\": " +
                      json_string(contextros::ros::ContextNode::carrier()));
  }

 private:
  static contextros::ros::ParticipantOptions announcing(const char* layer) {
    contextros::ros::ParticipantOptions options;
    options.layers = std::vector<std::string>{layer};
    return options;
  }
  std::unique_ptr<contextros::ros::ManagerFollower> follower_;
};

class Wheels : public Component {
 public:
  explicit Wheels(const rclcpp::NodeOptions& options)
      : Component("wheels", options, "Slow", drive) {}
};

class Lights : public Component {
 public:
  explicit Lights(const rclcpp::NodeOptions& options)
      : Component("lights", options, "Night", light) {}
};

}  // namespace contextros_rclcpp_tests

RCLCPP_COMPONENTS_REGISTER_NODE(contextros_rclcpp_tests::Wheels)
RCLCPP_COMPONENTS_REGISTER_NODE(contextros_rclcpp_tests::Lights)
