// A plain rcl node that follows the Layer manager: it prints its greeting every time the
// manager switches its layers, until SIGINT or SIGTERM.
#include <pthread.h>
#include <signal.h>

#include <contextros/ros/participant.hpp>
#include <contextros/ros/rcl_node.hpp>
#include <cstdio>
#include <string>

#include "greeting.layers.hpp"

int main(int argc, char** argv) {
  // Blocked before any thread starts, so that every thread leaves them to sigwait below.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  namespace ros = contextros::ros;
  ros::RclContext context(argc, argv);
  ros::RclNode node(context, "greeter_cpp");
  ros::ContextNode follower(node.get());
  ros::ContextNode::add_listener([](const ros::LayerState& state) {
    std::string layers;
    for (const auto& layer : state.active) layers += (layers.empty() ? "" : ",") + layer;
    std::printf("epoch %llu [%s]: %s\n", static_cast<unsigned long long>(state.epoch),
                layers.c_str(), greeting().c_str());
    std::fflush(stdout);
  });
  std::printf("ready\n");
  std::fflush(stdout);
  int received = 0;
  sigwait(&signals, &received);
  return 0;
}
