// A C++ context node in its own process, for the system tests and benchmarks: the twin of
// tests/ros/participant_process.py (same layers, relations, layered method and output).
//
// It prints one JSON line per event on stdout: `ready` (node, mode), `applied` (epoch,
// active, what the layered method now returns), `critical-open` / `critical-closed`.
// Commands on stdin: `critical SECONDS` holds a CriticalSection on another thread for that
// long; `drop-first` destroys the first node (the carrier of the process's participant: the
// --also node takes it over) and prints `dropped-first`; `quit` leaves like SIGINT / SIGTERM
// do (leaving=true).
//
// Options: --name NAME (required), --layers A,B (the layers it announces; default the six of
// participant_process.py's DEFAULT_LAYERS),
// --heartbeat SECONDS, --refuse LAYER (after announcing, LAYER is redefined to require a
// layer nobody has: the manager does not know, so this node refuses any state with it),
// --also NAME (a second node of this process, hosted by the first, announcing Night),
// --veto-sleep SECONDS (a veto that prints `veto-called` and takes that long to say yes).
#include <pthread.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <contextros/contextros.hpp>
#include <contextros/ros/participant.hpp>
#include <contextros/ros/rcl_node.hpp>
#include <cstdio>
#include <iostream>
#include <mutex>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "json_lines.hpp"

namespace {

using contextros::LayerInfo;

std::mutex output_mutex;

using contextros::test_output::json_list;
using contextros::test_output::json_string;

double monotonic_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// One JSON line: {"event": EVENT, "t": <monotonic s>, FIELDS}; `fields` already JSON.
void emit(const std::string& event, const std::string& fields = "") {
  std::lock_guard<std::mutex> lock(output_mutex);
  std::printf("{\"event\": %s, \"t\": %.6f%s%s}\n", json_string(event).c_str(),
              monotonic_seconds(), fields.empty() ? "" : ", ", fields.c_str());
  std::fflush(stdout);
}

// -- the layered method: what tests/ros/participant_process.py's Cleaner.mode does ---------

using ModeSignature = std::string();
using Proceed = contextros::ProceedOf<ModeSignature>;

std::string mode_base(Proceed) { return "base"; }
std::string mode_indoor(Proceed proceed) { return "wipe+" + proceed(); }
std::string mode_outdoor(Proceed proceed) { return "vacuum+" + proceed(); }
std::string mode_night(Proceed proceed) { return "quiet+" + proceed(); }

const std::vector<LayerInfo>& test_layers() {
  static const std::vector<LayerInfo> layers = {
      {"Indoor", {}, {}, {}, "location"}, {"Outdoor", {}, {}, {}, "location"},
      {"Night", {}, {}, {}, ""},          {"Slow", {"Fast"}, {}, {}, ""},
      {"Fast", {}, {}, {}, ""},           {"Gps", {}, {"Outdoor"}, {}, ""},
      // A hierarchy (issue 28): Mission implies Airborne, which implies Propulsion, CameraHigh.
      {"Mission", {}, {}, {}, "", {"Airborne"}},
      {"Airborne", {}, {}, {}, "", {"Propulsion", "CameraHigh"}},
      {"Propulsion", {}, {}, {}, ""},
      {"CameraHigh", {}, {}, {}, "camera"},
      {"CameraLow", {}, {}, {}, "camera"},
      {"Survey", {}, {}, {}, "", {"CameraHigh"}},
  };
  return layers;
}

// What a node announces without --layers (the hierarchy's layers only when asked for).
const std::vector<std::string> default_layers = {"Indoor", "Outdoor", "Night",
                                                 "Slow",   "Fast",    "Gps"};

bool define_test_layers() {
  for (const LayerInfo& layer : test_layers()) {
    contextros::define_layer(layer);
  }
  return true;
}
const bool layers_defined = define_test_layers();  // before the layered function below

contextros::LayeredOf<ModeSignature> mode_layered{
    "mode", &mode_base,
    {{"Indoor", &mode_indoor}, {"Outdoor", &mode_outdoor}, {"Night", &mode_night}}};

std::string mode() { return mode_layered.invoke(nullptr); }

// -- the program ----------------------------------------------------------------------------

struct Options {
  std::string name;
  std::optional<std::vector<std::string>> layers;
  double heartbeat = 0.25;
  std::string refuse;
  std::string also;
  double veto_sleep = -1;  // no veto
  std::string veto_throw;   // a veto that throws this
};

std::vector<std::string> split(const std::string& text) {
  std::vector<std::string> parts;
  std::stringstream stream(text);
  for (std::string part; std::getline(stream, part, ',');) {
    if (!part.empty()) parts.push_back(part);
  }
  return parts;
}

Options parse(int argc, char** argv) {
  Options options;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    const std::string value = argv[i + 1];
    if (flag == "--name") {
      options.name = value;
    } else if (flag == "--layers") {
      options.layers = split(value);
    } else if (flag == "--heartbeat") {
      options.heartbeat = std::stod(value);
    } else if (flag == "--refuse") {
      options.refuse = value;
    } else if (flag == "--also") {
      options.also = value;
    } else if (flag == "--veto-sleep") {
      options.veto_sleep = std::stod(value);
    } else if (flag == "--veto-throw") {
      options.veto_throw = value;
    } else if (flag == "--ros-args") {
      break;
    } else {
      throw std::invalid_argument("unknown option " + flag);
    }
  }
  if (options.name.empty()) {
    throw std::invalid_argument("--name NAME is required");
  }
  return options;
}

void hold_critical(double seconds) {
  contextros::CriticalSection section;
  emit("critical-open");
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  emit("critical-closed");
}

void read_commands() {
  for (std::string line; std::getline(std::cin, line);) {
    std::istringstream words(line);
    std::string command;
    words >> command;
    if (command == "critical") {
      double seconds = 0;
      words >> seconds;
      std::thread(hold_critical, seconds).detach();
    } else if (command == "drop-first") {
      ::kill(::getpid(), SIGUSR1);  // handled by main, which owns the nodes
    } else if (command == "quit") {
      ::kill(::getpid(), SIGTERM);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  (void)layers_defined;
  Options options;
  try {
    options = parse(argc, argv);
  } catch (const std::exception& error) {
    std::fprintf(stderr, "participant_process: %s\n", error.what());
    return 2;
  }
  // Signals are taken by sigwait below, on this thread only.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  sigaddset(&stop_signals, SIGUSR1);  // drop-first
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);

  contextros::ros::RclContext context(argc, argv);
  std::optional<contextros::ros::RclNode> node;
  node.emplace(context, options.name);
  contextros::ros::ParticipantOptions participant_options;
  participant_options.layers = options.layers ? options.layers : default_layers;
  participant_options.heartbeat_period = std::chrono::duration_cast<contextros::ros::Clock::duration>(
      std::chrono::duration<double>(options.heartbeat));
  std::optional<contextros::ros::ContextNode> follower;
  follower.emplace(node->get(), participant_options);
  contextros::ros::ContextNode::add_listener([](const contextros::ros::LayerState& state) {
    emit("applied", "\"epoch\": " + std::to_string(state.epoch) + ", \"active\": " +
                        json_list(state.active) + ", \"mode\": " + json_string(mode()));
  });
  if (options.veto_sleep >= 0) {
    const double seconds = options.veto_sleep;
    contextros::ros::ContextNode::add_veto([seconds](const contextros::ros::LayerState& proposal) {
      emit("veto-called", "\"epoch\": " + std::to_string(proposal.epoch));
      std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
      emit("veto-answered", "\"epoch\": " + std::to_string(proposal.epoch));
      return std::string();
    });
  }
  if (!options.veto_throw.empty()) {
    const std::string message = options.veto_throw;
    contextros::ros::ContextNode::add_veto(
        [message](const contextros::ros::LayerState&) -> std::string {
          throw std::runtime_error(message);
        });
  }
  if (!options.refuse.empty()) {
    // A later definition of a name replaces the earlier one; the participant announced the
    // earlier one, so the manager cannot know of this relation.
    contextros::define_layer(LayerInfo{options.refuse, {}, {"Sunlight"}, {}, ""});
  }
  std::optional<contextros::ros::RclNode> second;
  std::optional<contextros::ros::ContextNode> second_follower;
  if (!options.also.empty()) {
    second.emplace(context, options.also);
    contextros::ros::ParticipantOptions hosted_options;
    hosted_options.layers = std::vector<std::string>{"Night"};
    second_follower.emplace(second->get(), hosted_options);
  }
  std::thread(read_commands).detach();
  emit("ready", "\"node\": " + json_string(node->fully_qualified_name()) + ", \"mode\": " +
                    json_string(mode()));

  int signal_number = 0;
  while (sigwait(&stop_signals, &signal_number) == 0 && signal_number == SIGUSR1) {
    if (follower) {
      follower.reset();  // the carrier goes: the next node of the process takes over
      node.reset();
      emit("dropped-first", "\"carrier\": " + json_string(contextros::ros::ContextNode::carrier()));
    }
  }
  second_follower.reset();
  follower.reset();
  return 0;  // ContextNodes say they leave, then the nodes and the context go
}
