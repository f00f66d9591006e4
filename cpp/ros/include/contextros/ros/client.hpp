// The activation client in C++: asks the Layer manager for activations, as the Python
// `contextros.ros.LayerClient` does (docs/client.md), on any rcl node (a plain rcl program's,
// or an rclcpp node's `*node->get_node_base_interface()->get_rcl_node_handle()`).
//
//   contextros::ros::LayerClient client(node.get());
//   client.wait_for_manager(std::chrono::seconds(5));   // ManagerError if none answers
//   contextros::ros::CommandOptions sync;
//   sync.synchronous = true;
//   sync.timeout = std::chrono::seconds(2);
//   auto result = client.activate({"Outdoor"}, sync);    // ActivationFailed if refused
//
// One default, as on the command line: a command returns once the manager published the new
// state; `synchronous` returns once every live node applied it; `atomic` has every live node
// vote first. `timeout` is the command's deadline at the manager; the client gives up
// `reply_margin` later (ManagerError: outcome unknown). An asynchronous command unanswered
// after `resend_after` is sent again (at most `attempts` in all), never a synchronous or
// atomic one; an answer to any attempt counts, and where no resend would end before the
// client gives up, it waits for those sent. The blocking calls wait on a wait set of the
// client's own: call them from any thread but not concurrently on one client
// (`request_async` runs them on a thread of its own, one at a time); never from a callback
// that the answer would have to wait for. A ROS shutdown (Ctrl-C through rclcpp's handler)
// ends a waiting call within 100 ms with ManagerError, as does rcl failing during a command.
#pragma once

#include <chrono>
#include <cstdint>
#include <future>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "contextros/errors.hpp"

struct rcl_node_s;

namespace contextros::ros {

// The manager's answer (docs/client.md, "ActivationResult").
struct ActivationResult {
  bool success = false;
  // The manager's words: what was wrong, "no change", who did not acknowledge and why.
  std::string message;
  // The epoch of the state the answer is about (the current one when nothing changed).
  std::uint64_t epoch = 0;
  // Its layers, oldest first.
  std::vector<std::string> active;
  // Node names, for synchronous and atomic commands.
  std::vector<std::string> acknowledged;
  std::vector<std::string> not_acknowledged;
  // Seconds, as measured by the manager.
  double elapsed = 0.0;
};

// How a command is carried out (the Activate request's fields besides the layers).
struct CommandOptions {
  // false: answered once the new state is published; true: once every live node applied it.
  bool synchronous = false;
  // A two-phase activation: every live node votes first; all switch or none does.
  bool atomic = false;
  // The command's deadline, from its arrival at the manager; zero: the manager's default.
  std::chrono::duration<double> timeout{0.0};
  // Recorded with the state (`contextros watch`, `status`).
  std::string reason;
  // Synchronous and atomic: nodes, and a number of nodes, the command must reach.
  std::vector<std::string> expect_nodes;
  std::uint32_t expect_count = 0;
};

// No manager, or no answer in time (the outcome is then unknown).
class ManagerError : public LayerError {
 public:
  using LayerError::LayerError;
};

// A command refused, or not acknowledged in time, or invalid (then nothing was sent).
class ActivationFailed : public ManagerError {
 public:
  ActivationFailed(const std::string& message, std::vector<std::string> missing = {})
      : ManagerError(message), not_acknowledged(std::move(missing)) {}
  std::vector<std::string> not_acknowledged;
};

// As the Python client's constants (src/contextros/ros/client.py).
inline constexpr std::chrono::seconds reply_margin{2};
inline constexpr std::chrono::seconds assumed_default_timeout{10};
inline constexpr std::chrono::seconds resend_after{2};
inline constexpr int attempts = 3;

class LayerClient {
 public:
  // Service clients on `node` (not owned; it must outlive the client). `requester` is
  // recorded with every state it causes; "": "<user>@pid<pid>", as in Python.
  explicit LayerClient(rcl_node_s& node, std::string requester = "");
  ~LayerClient();
  LayerClient(const LayerClient&) = delete;
  LayerClient& operator=(const LayerClient&) = delete;

  // Returns once the manager's services are discovered and one of its answers came back
  // (a reply sent before the manager discovered this client would be lost); ManagerError
  // naming the domain otherwise.
  void wait_for_manager(std::chrono::duration<double> timeout = std::chrono::seconds(5));

  // Deactivates `deactivate`, then activates `activate`, in one new state; the manager's
  // answer, success or not. ActivationFailed for an invalid command (nothing sent),
  // ManagerError when no answer came `reply_margin` after the timeout, ROS shut down or rcl
  // failed (the outcome is then unknown).
  ActivationResult request(const std::vector<std::string>& activate,
                           const std::vector<std::string>& deactivate = {},
                           const CommandOptions& options = {});
  // The same on a thread of its own: the future holds the answer or the exception. The
  // client must outlive the future's completion.
  std::future<ActivationResult> request_async(std::vector<std::string> activate,
                                              std::vector<std::string> deactivate = {},
                                              CommandOptions options = {});

  // `request`, raising ActivationFailed (with the manager's message and the nodes that did
  // not acknowledge) instead of returning a failed answer.
  ActivationResult activate(const std::vector<std::string>& layers,
                            const CommandOptions& options = {});
  ActivationResult deactivate(const std::vector<std::string>& layers,
                              const CommandOptions& options = {});
  // `contextros switch`: `deactivate` off and `activate` on in one state.
  ActivationResult switch_layers(const std::vector<std::string>& deactivate,
                                 const std::vector<std::string>& activate,
                                 const CommandOptions& options = {});

  const std::string& requester() const;
  // The activation service's name as resolved in the node's namespace.
  std::string service_name() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// What is wrong with a command before it is sent (empty: nothing), as the Python client
// checks it: the timeout, and text the manager would refuse (control characters, NUL).
std::vector<std::string> command_problems(const std::vector<std::string>& activate,
                                          const std::vector<std::string>& deactivate,
                                          const CommandOptions& options,
                                          const std::string& requester);

}  // namespace contextros::ros
