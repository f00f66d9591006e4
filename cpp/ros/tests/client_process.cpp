// The C++ activation client (contextros/ros/client.hpp) in a process of its own, driven by
// tests/ros/test_cpp_client.py: one command per line on stdin, one JSON line per answer on
// stdout.
//
//   wait SECONDS                      wait_for_manager -> {"event": "manager"}
//   request|activate|deactivate|switch|async [on=A,B] [off=C] [sync] [atomic]
//           [timeout=SECONDS] [expect=/n1,/n2] [count=N] [reason=WORD]
//        -> {"event": "answer", "success": .., "message": .., "epoch": .., "active": [..],
//            "acknowledged": [..], "not_acknowledged": [..], "elapsed": ..}
//   (`activate` takes on=, `deactivate` off=, `switch` both; `async` is request_async.)
//   Errors: {"event": "error", "kind": "ActivationFailed"|"ManagerError", "message": ..,
//            "not_acknowledged": [..]}
// Options: --name NAME (the node; default cpp_client), --requester TEXT.
// SIGINT or SIGTERM shuts the ROS context down, as rclcpp's signal handler does: a command
// waiting for its answer ends (ManagerError), then {"event": "shutdown"} and exit 0.
#include <pthread.h>
#include <rcl/error_handling.h>
#include <rcl/rcl.h>
#include <signal.h>

#include <contextros/ros/client.hpp>
#include <contextros/ros/rcl_node.hpp>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "json_lines.hpp"

namespace {

using contextros::ros::ActivationFailed;
using contextros::ros::ActivationResult;
using contextros::ros::CommandOptions;
using contextros::ros::ManagerError;

using contextros::test_output::json_list;
using contextros::test_output::json_string;

std::vector<std::string> split(const std::string& text) {
  std::vector<std::string> parts;
  std::stringstream stream(text);
  for (std::string part; std::getline(stream, part, ',');) {
    parts.push_back(part);
  }
  return parts;
}

void print(const std::string& line) { std::cout << line << std::endl; }

void print_answer(const ActivationResult& result) {
  char numbers[96];
  std::snprintf(numbers, sizeof numbers, "\"epoch\": %llu, \"elapsed\": %.6f",
                static_cast<unsigned long long>(result.epoch), result.elapsed);
  print(std::string("{\"event\": \"answer\", \"success\": ") +
        (result.success ? "true" : "false") + ", \"message\": " + json_string(result.message) +
        ", " + numbers + ", \"active\": " + json_list(result.active) +
        ", \"acknowledged\": " + json_list(result.acknowledged) +
        ", \"not_acknowledged\": " + json_list(result.not_acknowledged) + "}");
}

void print_error(const char* kind, const std::string& message,
                 const std::vector<std::string>& not_acknowledged = {}) {
  print(std::string("{\"event\": \"error\", \"kind\": \"") + kind + "\", \"message\": " +
        json_string(message) + ", \"not_acknowledged\": " + json_list(not_acknowledged) + "}");
}

// One command line: its verb, layers and options.
struct Command {
  std::string verb;
  std::vector<std::string> on;
  std::vector<std::string> off;
  CommandOptions options;
  double seconds = 5.0;
};

Command parse(const std::string& line) {
  Command command;
  std::stringstream words(line);
  words >> command.verb;
  for (std::string word; words >> word;) {
    const auto equals = word.find('=');
    const std::string key = word.substr(0, equals);
    const std::string value = equals == std::string::npos ? "" : word.substr(equals + 1);
    if (key == "on") {
      command.on = split(value);
    } else if (key == "off") {
      command.off = split(value);
    } else if (key == "sync") {
      command.options.synchronous = true;
    } else if (key == "atomic") {
      command.options.atomic = true;
    } else if (key == "timeout") {
      command.options.timeout = std::chrono::duration<double>(std::stod(value));
    } else if (key == "expect") {
      command.options.expect_nodes = split(value);
    } else if (key == "count") {
      command.options.expect_count = static_cast<std::uint32_t>(std::stoul(value));
    } else if (key == "reason") {
      command.options.reason = value;
    } else if (command.verb == "wait") {
      command.seconds = std::stod(key);
    } else {
      throw std::invalid_argument("unknown word '" + word + "'");
    }
  }
  return command;
}

ActivationResult run(contextros::ros::LayerClient& client, const Command& command) {
  if (command.verb == "request") {
    return client.request(command.on, command.off, command.options);
  }
  if (command.verb == "async") {
    return client.request_async(command.on, command.off, command.options).get();
  }
  if (command.verb == "activate") {
    return client.activate(command.on, command.options);
  }
  if (command.verb == "deactivate") {
    return client.deactivate(command.off, command.options);
  }
  if (command.verb == "switch") {
    return client.switch_layers(command.off, command.on, command.options);
  }
  throw std::invalid_argument("unknown command '" + command.verb + "'");
}

// SIGINT and SIGTERM shut `context` down, from a thread of its own (rcl_shutdown is not
// async-signal-safe); SIGUSR1 ends that thread. Block the signals first (`blocked`), before
// rcl starts any thread.
class ShutdownOnSignal {
 public:
  static sigset_t blocked() {
    sigset_t signals;
    sigemptyset(&signals);
    sigaddset(&signals, SIGINT);
    sigaddset(&signals, SIGTERM);
    sigaddset(&signals, SIGUSR1);
    pthread_sigmask(SIG_BLOCK, &signals, nullptr);
    return signals;
  }

  ShutdownOnSignal(const sigset_t& signals, rcl_context_t& context)
      : watcher_([signals, &context] {
          int number = 0;
          if (sigwait(&signals, &number) == 0 && number != SIGUSR1) {
            if (rcl_shutdown(&context) != RCL_RET_OK) {
              rcl_reset_error();
            }
          }
        }) {}
  ~ShutdownOnSignal() {
    pthread_kill(watcher_.native_handle(), SIGUSR1);
    watcher_.join();
  }
  ShutdownOnSignal(const ShutdownOnSignal&) = delete;
  ShutdownOnSignal& operator=(const ShutdownOnSignal&) = delete;

 private:
  std::thread watcher_;
};

}  // namespace

int main(int argc, char** argv) {
  std::string name = "cpp_client";
  std::string requester;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string option = argv[i];
    if (option == "--name") {
      name = argv[i + 1];
    } else if (option == "--requester") {
      requester = argv[i + 1];
    }
  }
  const sigset_t signals = ShutdownOnSignal::blocked();
  contextros::ros::RclContext context(0, nullptr);
  const ShutdownOnSignal shutdown_on_signal(signals, context.get());
  contextros::ros::RclNode node(context, name);
  contextros::ros::LayerClient client(node.get(), requester);
  print("{\"event\": \"ready\", \"requester\": " + json_string(client.requester()) +
        ", \"service\": " + json_string(client.service_name()) + "}");
  for (std::string line; std::getline(std::cin, line);) {
    if (line.empty()) {
      continue;
    }
    try {
      const Command command = parse(line);
      if (command.verb == "quit") {
        break;
      }
      if (command.verb == "wait") {
        client.wait_for_manager(std::chrono::duration<double>(command.seconds));
        print("{\"event\": \"manager\"}");
      } else {
        print_answer(run(client, command));
      }
    } catch (const ActivationFailed& failure) {
      print_error("ActivationFailed", failure.what(), failure.not_acknowledged);
    } catch (const ManagerError& error) {
      print_error("ManagerError", error.what());
    } catch (const std::exception& error) {
      print_error("usage", error.what());
    }
    if (!context.ok()) {
      print("{\"event\": \"shutdown\"}");
      break;
    }
  }
  return 0;
}
