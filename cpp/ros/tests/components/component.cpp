// A component library, loaded with dlopen() into components_host as a component container
// loads its components: its own rcl node following the Layer manager, reporting its layered
// behaviour on every switch. Built twice (wheels, lights) from this file; COMPONENT names it
// and BEHAVIOUR is its layered function (from COMPONENT.cpp.layers).
#include <contextros/activation.hpp>
#include <contextros/ros/participant.hpp>
#include <contextros/ros/rcl_node.hpp>
#include <cstdio>
#include <memory>
#include <string>

#include COMPONENT_LAYERS_HEADER

namespace {

namespace ros = contextros::ros;

struct Component {
  ros::RclContext context;
  ros::RclNode node;
  ros::ContextNode follower;
  Component(int argc, const char* const* argv)
      : context(argc, argv), node(context, COMPONENT), follower(node.get()) {}
};

std::unique_ptr<Component> component;

}  // namespace

extern "C" void contextros_component_start(int argc, const char* const* argv) {
  component = std::make_unique<Component>(argc, argv);
  ros::ContextNode::add_listener([](const ros::LayerState& state) {
    std::printf("%s epoch %llu carrier %s: %s\n", COMPONENT,
                static_cast<unsigned long long>(state.epoch),
                ros::ContextNode::carrier().c_str(), BEHAVIOUR().c_str());
    std::fflush(stdout);
  });
  std::printf("%s started, carrier %s\n", COMPONENT, ros::ContextNode::carrier().c_str());
  std::fflush(stdout);
}

extern "C" void contextros_component_stop() { component.reset(); }
