// The activation client on rcl (contextros/ros/client.hpp): the Activate and QueryRegistry
// service clients on the user's node, waited on in a wait set of the client's own.
#include "contextros/ros/client.hpp"

#include <pwd.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <contextros_interfaces/srv/activate.hpp>
#include <contextros_interfaces/srv/query_registry.hpp>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <rcl/graph.h>
#include <rosidl_typesupport_cpp/service_type_support.hpp>
#include <thread>
#include <utility>

#include "contextros/ros/rcl_handles.hpp"
#include "contextros/ros/topics.hpp"

namespace contextros::ros {

namespace {

using Seconds = std::chrono::duration<double>;
using contextros_interfaces::srv::Activate;
using contextros_interfaces::srv::QueryRegistry;

// As the Python client (src/contextros/ros/client.py) and its validation
// (src/contextros/protocol/validation.py).
constexpr auto poll_period = std::chrono::milliseconds(10);
// The longest wait for an answer between two looks at the ROS context: a shutdown (Ctrl-C)
// ends a blocked call within it (rcl_wait does not wake on shutdown).
constexpr auto shutdown_check_period = std::chrono::milliseconds(100);
constexpr Seconds first_probe_wait{0.2};
constexpr Seconds longest_probe_wait{1.6};
constexpr double max_timeout = 3600.0;
constexpr std::size_t max_layers = 256;
constexpr std::size_t max_expected = 1024;
constexpr std::size_t max_name_length = 256;
constexpr std::size_t max_text_length = 1024;

std::string seconds_text(Seconds seconds) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", seconds.count());
  return text;
}

std::string default_requester() {
  std::string user;
  for (const char* variable : {"LOGNAME", "USER", "LNAME", "USERNAME"}) {
    const char* value = std::getenv(variable);
    if (value != nullptr && *value != '\0') {
      user = value;
      break;
    }
  }
  if (user.empty()) {
    const passwd* entry = getpwuid(geteuid());
    user = entry != nullptr ? entry->pw_name : "unknown";
  }
  return user + "@pid" + std::to_string(getpid());
}

bool has_control_characters(const std::string& text) {
  for (const char c : text) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {
      return true;
    }
  }
  return false;
}

std::string text_problem(const std::string& text, const std::string& field, std::size_t limit) {
  if (text.size() > limit) {
    return field + " is longer than " + std::to_string(limit) + " characters";
  }
  if (has_control_characters(text)) {
    return field + " has control characters";
  }
  return "";
}

void names_problems(const std::vector<std::string>& names, const std::string& field,
                    std::size_t limit, std::vector<std::string>& problems) {
  if (names.size() > limit) {
    problems.push_back(field + " lists " + std::to_string(names.size()) + " names, more than " +
                       std::to_string(limit));
    return;
  }
  for (const std::string& name : names) {
    std::string problem = name.empty() ? field + " entry is empty"
                                       : text_problem(name, field + " entry", max_name_length);
    if (!problem.empty()) {
      problems.push_back(std::move(problem));
    }
  }
}

// rcl failing while a command or a probe is under way: the client's documented error
// (ManagerError: the outcome is unknown), with rcl's words.
void check_command(rcl_ret_t ret, const char* what) {
  try {
    detail::check(ret, what);
  } catch (const ParticipantError& error) {
    throw ManagerError(error.what());
  }
}

rmw_qos_profile_t service_qos() {
  // ACTIVATE_QOS / QUERY_QOS (src/contextros/ros/topics.py).
  return keep_last(1000);
}

// An rcl service client on `node`, finalised with it.
class RclClient : detail::NonCopyable {
 public:
  RclClient(rcl_node_t& node, const rosidl_service_type_support_t* type, const char* service)
      : node_(node) {
    rcl_client_options_t options = rcl_client_get_default_options();
    options.qos = service_qos();
    detail::check(rcl_client_init(&handle_, &node_, type, service, &options),
                  std::string("cannot create a client of ").append(service).c_str());
  }
  ~RclClient() { detail::ignore_failure(rcl_client_fini(&handle_, &node_)); }
  rcl_client_t* get() { return &handle_; }

  bool server_available() {
    bool available = false;
    if (rcl_service_server_is_available(&node_, &handle_, &available) != RCL_RET_OK) {
      rcl_reset_error();
      return false;
    }
    return available;
  }

  template <class Request>
  std::int64_t send(const Request& request) {
    std::int64_t sequence = 0;
    check_command(rcl_send_request(&handle_, &request, &sequence), "cannot send a request");
    return sequence;
  }

  // The next response waiting, if any, with the sequence number of its request.
  template <class Response>
  bool take(Response& response, std::int64_t& sequence) {
    rmw_service_info_t info{};
    if (rcl_take_response_with_info(&handle_, &info, &response) != RCL_RET_OK) {
      rcl_reset_error();  // RCL_RET_CLIENT_TAKE_FAILED: nothing waiting
      return false;
    }
    sequence = info.request_id.sequence_number;
    return true;
  }

 private:
  rcl_node_t& node_;
  rcl_client_t handle_ = rcl_get_zero_initialized_client();
};

// A wait set for one service client.
class ClientWaitSet : detail::NonCopyable {
 public:
  explicit ClientWaitSet(rcl_context_t* context) : context_(context) {
    detail::check(rcl_wait_set_init(&handle_, 0, 0, 0, 1, 0, 0, context,
                                    rcl_get_default_allocator()),
                  "cannot create a wait set");
  }
  ~ClientWaitSet() { detail::ignore_failure(rcl_wait_set_fini(&handle_)); }

  // Waits until `client` has a response, `deadline` passes or shutdown_check_period
  // passed (the caller looks at the context again).
  void wait(rcl_client_t* client, Clock::time_point deadline) {
    const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(
        std::min(deadline - Clock::now(), Clock::duration(shutdown_check_period)));
    if (left.count() <= 0) {
      return;
    }
    detail::ignore_failure(rcl_wait_set_clear(&handle_));
    detail::ignore_failure(rcl_wait_set_add_client(&handle_, client, nullptr));
    const rcl_ret_t ret = rcl_wait(&handle_, left.count());
    if (ret != RCL_RET_OK && ret != RCL_RET_TIMEOUT) {
      if (!rcl_context_is_valid(context_)) {  // shut down meanwhile: the caller says so
        rcl_reset_error();
        return;
      }
      check_command(ret, "cannot wait for the Layer manager's answer");
    }
  }

 private:
  rcl_context_t* context_;
  rcl_wait_set_t handle_ = rcl_get_zero_initialized_wait_set();
};

ActivationResult result_of(const Activate::Response& response) {
  ActivationResult result;
  result.success = response.success;
  result.message = response.message;
  result.epoch = response.epoch;
  result.active = response.active_layers;
  result.acknowledged = response.acknowledged;
  result.not_acknowledged = response.not_acknowledged;
  result.elapsed = response.elapsed;
  return result;
}

ActivationResult checked(ActivationResult result) {
  if (!result.success) {
    throw ActivationFailed(result.message, result.not_acknowledged);
  }
  return result;
}

}  // namespace

std::vector<std::string> command_problems(const std::vector<std::string>& activate,
                                          const std::vector<std::string>& deactivate,
                                          const CommandOptions& options,
                                          const std::string& requester) {
  std::vector<std::string> problems;
  names_problems(activate, "activate", max_layers, problems);
  names_problems(deactivate, "deactivate", max_layers, problems);
  names_problems(options.expect_nodes, "expect_nodes", max_expected, problems);
  for (std::string problem : {text_problem(requester, "requester", max_text_length),
                              text_problem(options.reason, "reason", max_text_length)}) {
    if (!problem.empty()) {
      problems.push_back(std::move(problem));
    }
  }
  const double timeout = options.timeout.count();
  if (!std::isfinite(timeout)) {
    problems.push_back("timeout is not a finite number of seconds");
  } else if (timeout < 0 || timeout > max_timeout) {
    problems.push_back("timeout " + seconds_text(options.timeout) + " s is outside 0..3600 s");
  }
  return problems;
}

struct LayerClient::Impl {
  Impl(rcl_node_t& node, std::string requester)
      : node(node),
        requester(requester.empty() ? default_requester() : std::move(requester)),
        activate(node, rosidl_typesupport_cpp::get_service_type_support_handle<Activate>(),
                 activate_service),
        query(node, rosidl_typesupport_cpp::get_service_type_support_handle<QueryRegistry>(),
              query_service),
        activate_wait(node.context),
        query_wait(node.context) {}

  bool context_ok() { return rcl_context_is_valid(node.context); }

  std::string domain() {
    const char* domain = std::getenv("ROS_DOMAIN_ID");
    return domain != nullptr && *domain != '\0' ? domain : "0";
  }

  // The answer to any of the requests numbered `sequences` (the attempts of one command),
  // if it comes before `deadline` (answers to abandoned commands' requests are dropped).
  bool answer(const std::vector<std::int64_t>& sequences, Clock::time_point deadline,
              Activate::Response& response) {
    while (context_ok()) {
      std::int64_t answered = 0;
      while (activate.take(response, answered)) {
        if (std::find(sequences.begin(), sequences.end(), answered) != sequences.end()) {
          return true;
        }
      }
      if (Clock::now() >= deadline) {
        return false;
      }
      activate_wait.wait(activate.get(), deadline);
    }
    return false;
  }

  rcl_node_t& node;
  const std::string requester;
  RclClient activate;
  RclClient query;
  ClientWaitSet activate_wait;
  ClientWaitSet query_wait;
  std::mutex busy;  // one command at a time (their answers share the client)
};

LayerClient::LayerClient(rcl_node_s& node, std::string requester)
    : impl_(std::make_unique<Impl>(node, std::move(requester))) {}

LayerClient::~LayerClient() = default;

const std::string& LayerClient::requester() const { return impl_->requester; }

std::string LayerClient::service_name() const {
  const char* name = rcl_client_get_service_name(impl_->activate.get());
  return name != nullptr ? name : activate_service;
}

void LayerClient::wait_for_manager(std::chrono::duration<double> timeout) {
  std::lock_guard<std::mutex> lock(impl_->busy);
  const auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(timeout);
  while (!(impl_->activate.server_available() && impl_->query.server_available())) {
    if (!impl_->context_ok()) {
      throw ManagerError("ROS was shut down while waiting for the Layer manager on " +
                         service_name());
    }
    if (Clock::now() >= deadline) {
      throw ManagerError("no Layer manager answers on " + service_name() +
                         " (ROS_DOMAIN_ID=" + impl_->domain() + ") after " +
                         seconds_text(timeout) +
                         " s; start one with `contextros manager` (in the same namespace: "
                         "`--ros-args -r __ns:=...`)");
    }
    std::this_thread::sleep_for(poll_period);
  }
  // A probe is sent again, less and less often, and any probe's answer will do (a reply
  // can be lost while the manager has not discovered this client yet).
  Seconds wait = first_probe_wait;
  while (true) {
    impl_->query.send(QueryRegistry::Request());
    const auto until =
        std::min(deadline, Clock::now() + std::chrono::duration_cast<Clock::duration>(wait));
    QueryRegistry::Response response;
    std::int64_t sequence = 0;
    while (impl_->context_ok()) {
      if (impl_->query.take(response, sequence)) {
        return;
      }
      if (Clock::now() >= until) {
        break;
      }
      impl_->query_wait.wait(impl_->query.get(), until);
    }
    if (Clock::now() >= deadline || !impl_->context_ok()) {
      throw ManagerError("the Layer manager on " + service_name() + " did not answer within " +
                         seconds_text(timeout) + " s");
    }
    wait = std::min(2 * wait, longest_probe_wait);
  }
}

ActivationResult LayerClient::request(const std::vector<std::string>& activate,
                                      const std::vector<std::string>& deactivate,
                                      const CommandOptions& options) {
  const std::vector<std::string> problems =
      command_problems(activate, deactivate, options, impl_->requester);
  if (!problems.empty()) {
    std::string text;
    for (const std::string& problem : problems) {
      text += (text.empty() ? "" : "; ") + problem;
    }
    throw ActivationFailed("invalid command: " + text + "; nothing sent");
  }
  Activate::Request request;
  request.activate = activate;
  request.deactivate = deactivate;
  request.synchronous = options.synchronous;
  request.timeout = options.timeout.count();
  request.requester = impl_->requester;
  request.reason = options.reason;
  request.expect_nodes = options.expect_nodes;
  request.expect_count = options.expect_count;
  request.atomic = options.atomic;

  std::lock_guard<std::mutex> lock(impl_->busy);
  const auto started = Clock::now();
  const Seconds bound =
      (options.timeout.count() > 0 ? options.timeout : Seconds(assumed_default_timeout)) +
      reply_margin;
  const auto give_up = started + std::chrono::duration_cast<Clock::duration>(bound);
  // Only an asynchronous command is sent again: a synchronous one's answer may take until
  // its timeout, and an aborted atomic vote must not be started again behind its caller.
  const bool resend = !(options.synchronous || options.atomic);
  std::vector<std::int64_t> sent;  // the command's attempts: an answer to any will do
  for (int attempt = 1; attempt <= attempts; ++attempt) {
    sent.push_back(impl_->activate.send(request));
    bool last = !resend || attempt == attempts;
    const auto until = last ? give_up : std::min(give_up, Clock::now() + resend_after);
    Activate::Response response;
    bool answered = impl_->answer(sent, until, response);
    // A command sent again must end before this client gives up, as the first: where none
    // would (a short timeout), those sent are waited for until then.
    const Seconds left = give_up - Clock::now() - reply_margin;
    if (!answered && !last && left.count() <= 0) {
      answered = impl_->answer(sent, give_up, response);
      last = true;
    }
    if (answered) {
      return result_of(response);
    }
    if (last || !impl_->context_ok()) {
      break;
    }
    request.timeout = left.count();
  }
  char elapsed[32];
  std::snprintf(elapsed, sizeof elapsed, "%.1f", Seconds(Clock::now() - started).count());
  const std::string unknown =
      " s; whether the command was carried out is unknown (see `contextros status`)";
  if (!impl_->context_ok()) {
    throw ManagerError(std::string("ROS was shut down before the Layer manager answered, after ") +
                       elapsed + unknown);
  }
  throw ManagerError(std::string("the Layer manager did not answer within ") + elapsed + unknown);
}

std::future<ActivationResult> LayerClient::request_async(std::vector<std::string> activate,
                                                         std::vector<std::string> deactivate,
                                                         CommandOptions options) {
  return std::async(std::launch::async,
                    [this, activate = std::move(activate), deactivate = std::move(deactivate),
                     options = std::move(options)] {
                      return request(activate, deactivate, options);
                    });
}

ActivationResult LayerClient::activate(const std::vector<std::string>& layers,
                                       const CommandOptions& options) {
  return checked(request(layers, {}, options));
}

ActivationResult LayerClient::deactivate(const std::vector<std::string>& layers,
                                         const CommandOptions& options) {
  return checked(request({}, layers, options));
}

ActivationResult LayerClient::switch_layers(const std::vector<std::string>& deactivate,
                                            const std::vector<std::string>& activate,
                                            const CommandOptions& options) {
  return checked(request(activate, deactivate, options));
}

}  // namespace contextros::ros
