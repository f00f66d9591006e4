// An rclcpp::Node following the Layer manager with follow_manager(*this), for
// tests/ros/test_rclcpp.py. Its layers: Indoor and Outdoor (group location), Night, Slow
// (excludes Fast), Fast; its layered `mode()` is read by a wall timer of the node's own
// executor, which prints every change. Events: `ready`, `applied` (epoch, active, mode, from
// the participant's listener), `mode` (what the timer saw), `stopped` (after rclcpp::spin
// returned: whether it still followed the manager). Options: --name NAME, --veto TEXT (an
// application veto refusing every atomic proposal with TEXT). Stops on SIGINT/SIGTERM
// through rclcpp's own signal handler.
#include <chrono>
#include <contextros/contextros.hpp>
#include <contextros/ros/rclcpp.hpp>
#include <memory>
#include <rclcpp/rclcpp.hpp>
#include <rclcpp/version.h>
#include <string>
#include <vector>

#include "../json_lines.hpp"

namespace {

using contextros::LayerInfo;
using contextros::test_output::emit;
using contextros::test_output::json_list;
using contextros::test_output::json_string;

using ModeSignature = std::string();
using Proceed = contextros::ProceedOf<ModeSignature>;

bool define_layers() {
  for (const LayerInfo& layer : std::vector<LayerInfo>{{"Indoor", {}, {}, {}, "location"},
                                                       {"Outdoor", {}, {}, {}, "location"},
                                                       {"Night", {}, {}, {}, ""},
                                                       {"Slow", {"Fast"}, {}, {}, ""},
                                                       {"Fast", {}, {}, {}, ""}}) {
    contextros::define_layer(layer);
  }
  return true;
}
const bool layers_defined = define_layers();  // before the layered function below

contextros::LayeredOf<ModeSignature> mode_layered{
    "mode",
    [](Proceed) -> std::string { return "base"; },
    {{"Indoor", [](Proceed proceed) { return "wipe+" + proceed(); }},
     {"Outdoor", [](Proceed proceed) { return "vacuum+" + proceed(); }},
     {"Night", [](Proceed proceed) { return "quiet+" + proceed(); }}}};

std::string mode() { return mode_layered.invoke(nullptr); }

class Cleaner : public rclcpp::Node {
 public:
  Cleaner(const std::string& name, const std::string& veto)
      : Node(name), follower_(contextros::ros::follow_manager(*this)) {
    if (!veto.empty()) {
      contextros::ros::ContextNode::add_veto(
          [veto](const contextros::ros::LayerState&) { return veto; });
    }
    timer_ = create_wall_timer(std::chrono::milliseconds(20), [this] {
      const std::string now = mode();
      if (now != seen_) {
        seen_ = now;
        emit("mode", "\"mode\": " + json_string(now));
      }
    });
  }
  bool following() const { return follower_->following(); }

 private:
  std::unique_ptr<contextros::ros::ManagerFollower> follower_;
  rclcpp::TimerBase::SharedPtr timer_;
  std::string seen_;
};

}  // namespace

int main(int argc, char** argv) {
  (void)layers_defined;
  const std::vector<std::string> arguments = rclcpp::init_and_remove_ros_arguments(argc, argv);
  std::string name = "rclcpp_cleaner";
  std::string veto;
  for (std::size_t i = 1; i + 1 < arguments.size(); i += 2) {
    (arguments[i] == "--name" ? name : veto) = arguments[i + 1];
  }
  contextros::ros::ContextNode::add_listener([](const contextros::ros::LayerState& state) {
    emit("applied", "\"epoch\": " + std::to_string(state.epoch) + ", \"active\": " +
                        json_list(state.active) + ", \"mode\": " + json_string(mode()));
  });
  auto node = std::make_shared<Cleaner>(name, veto);
  emit("ready", "\"node\": " + json_string(node->get_fully_qualified_name()) + ", \"rclcpp\": " +
                    json_string(RCLCPP_VERSION_STR));
  rclcpp::spin(node);
  emit("stopped", std::string("\"following\": ") + (node->following() ? "true" : "false"));
  rclcpp::shutdown();
  return 0;
}
