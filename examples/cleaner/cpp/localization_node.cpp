// The cleaning robot's localization node in C++: a plain rcl program (it builds against the
// ROS 2 pip wheels, which have no rclcpp) whose context-dependent behaviour comes from
// localization.cpp.layers, switched by the Layer manager together with the Python nodes.
//
// The C++ twin of ../localization.py, with the same topics and output: it estimates the
// robot's pose on every gyro reading (`imu`), from the wheels (`wheel_speed`) and the GPS
// (`gps/fix`) as the active location layer says, publishes it on `pose`, and prints when
// the source of its estimate changes. It also prints, for every state it applies, how long
// after the manager's publication that was.
//
// Run: build/cpp/examples/cleaner/cleaner_localization [--ros-args ...] (make demo does).
#include <pthread.h>
#include <signal.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <contextros/activation.hpp>
#include <contextros/errors.hpp>
#include <contextros/ros/participant.hpp>
#include <contextros/ros/rcl_handles.hpp>
#include <contextros/ros/rcl_node.hpp>
#include <cstdio>
#include <functional>
#include <geometry_msgs/msg/pose_stamped.hpp>
#include <geometry_msgs/msg/twist_stamped.hpp>
#include <optional>
#include <sensor_msgs/msg/imu.hpp>
#include <sensor_msgs/msg/nav_sat_fix.hpp>
#include <sensor_msgs/msg/nav_sat_status.hpp>
#include <string>
#include <thread>

#include "localization.layers.hpp"

namespace {

namespace ros = contextros::ros;
using sensor_msgs::msg::Imu;
using sensor_msgs::msg::NavSatFix;
using sensor_msgs::msg::NavSatStatus;

// The demo GPS's local frame (../gps_frame.py): metres east and north of Tokyo Station.
constexpr double origin_latitude = 35.6812;
constexpr double origin_longitude = 139.7671;
constexpr double metres_per_degree = 111320.0;
constexpr double pi = 3.14159265358979323846;

std::pair<double, double> to_local(double latitude, double longitude) {
  const double x = (longitude - origin_longitude) * metres_per_degree *
                   std::cos(origin_latitude * pi / 180.0);
  const double y = (latitude - origin_latitude) * metres_per_degree;
  return {x, y};
}

double wall_seconds() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// Waits for SIGINT / SIGTERM (blocked in every thread) on a thread of its own, then calls
// `on_signal`; joined on destruction (woken by a SIGTERM of its own if none came).
class SignalWaiter {
 public:
  SignalWaiter(const sigset_t& signals, std::function<void()> on_signal)
      : thread_([this, signals, on_signal = std::move(on_signal)] {
          int signal_number = 0;
          sigwait(&signals, &signal_number);
          done_ = true;
          on_signal();
        }) {}
  ~SignalWaiter() {
    if (!done_) pthread_kill(thread_.native_handle(), SIGTERM);
    thread_.join();
  }
  SignalWaiter(const SignalWaiter&) = delete;
  SignalWaiter& operator=(const SignalWaiter&) = delete;

 private:
  std::atomic<bool> done_{false};
  std::thread thread_;
};

std::string joined(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& name : names) out += (out.empty() ? "" : ", ") + name;
  return out;
}

class Localization {
 public:
  explicit Localization(ros::RclNode& node)
      : imu_(node.get(), ros::type_support<Imu>(), "imu", ros::keep_last(10)),
        wheels_(node.get(), ros::type_support<geometry_msgs::msg::TwistStamped>(), "wheel_speed",
                ros::keep_last(10)),
        gps_(node.get(), ros::type_support<NavSatFix>(), "gps/fix", ros::keep_last(10)),
        pose_pub_(node.get(), ros::type_support<geometry_msgs::msg::PoseStamped>(), "pose",
                  ros::keep_last(10)) {}

  // The subscriptions, for the program's wait set.
  ros::RclSubscription& imu() { return imu_; }
  ros::RclSubscription& wheels() { return wheels_; }
  ros::RclSubscription& gps() { return gps_; }

  void on_wheels() {
    geometry_msgs::msg::TwistStamped message;
    while (wheels_.take(message)) speed_ = message.twist.linear.x;
  }

  void on_gps() {
    NavSatFix message;
    while (gps_.take(message)) {
      const bool has_fix = message.status.status >= NavSatStatus::STATUS_FIX;
      gps_fix_ = has_fix ? std::optional(to_local(message.latitude, message.longitude))
                         : std::nullopt;
    }
  }

  void on_gyro() {
    Imu message;
    while (imu_.take(message)) {
      const double stamp = message.header.stamp.sec + message.header.stamp.nanosec * 1e-9;
      const double dt = last_stamp_ ? stamp - *last_stamp_ : 0.0;
      last_stamp_ = stamp;
      if (contextros::active_layers().empty()) {
        continue;  // the manager has not said where we are yet
      }
      // The layered call: the active location layer's estimate_pose. The manager may switch
      // to no layer right after the check above.
      Pose pose;
      try {
        pose = estimate_pose(pose_, Sensors{message.angular_velocity.z, speed_, gps_fix_}, dt);
      } catch (const contextros::NoImplementationError&) {
        continue;
      }
      gps_fix_.reset();  // each fix is used once
      if (pose.source != pose_.source) {
        std::printf("position from the %s now: (%.1f, %.1f)\n", pose.source.c_str(), pose.x,
                    pose.y);
        std::fflush(stdout);
      }
      pose_ = pose;
      publish(message.header.stamp);
    }
  }

 private:
  void publish(const builtin_interfaces::msg::Time& stamp) {
    geometry_msgs::msg::PoseStamped message;
    message.header.stamp = stamp;
    message.header.frame_id = "map";
    message.pose.position.x = pose_.x;
    message.pose.position.y = pose_.y;
    message.pose.orientation.z = std::sin(pose_.heading / 2);
    message.pose.orientation.w = std::cos(pose_.heading / 2);
    pose_pub_.publish(message);
  }

  ros::RclSubscription imu_;
  ros::RclSubscription wheels_;
  ros::RclSubscription gps_;
  ros::RclPublisher pose_pub_;
  Pose pose_{0.0, 0.0, 0.0, "none"};
  double speed_ = 0.0;
  std::optional<std::pair<double, double>> gps_fix_;
  std::optional<double> last_stamp_;
};

}  // namespace

int main(int argc, char** argv) {
  // SIGINT / SIGTERM end the loop below (taken by a thread of their own), so that the
  // ContextNode can tell the manager it leaves.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
  try {
    ros::RclContext context(argc, argv);
    ros::RclNode node(context, "localization");
    ros::RclGuardCondition stop(&context.get());
    std::atomic<bool> stopping{false};
    SignalWaiter signals(stop_signals, [&] {
      stopping = true;
      stop.trigger();
    });

    Localization localization(node);
    // Follows the Layer manager: announces Indoor and Outdoor (from the layer file).
    ros::ContextNode follower(node.get());
    ros::ContextNode::add_listener([](const ros::LayerState& state) {
      const double after_ms = (wall_seconds() - state.stamp) * 1000.0;
      std::printf("applied epoch %llu [%s] %.1f ms after the manager published it\n",
                  static_cast<unsigned long long>(state.epoch), joined(state.active).c_str(),
                  after_ms);
      std::fflush(stdout);
    });
    std::printf("localization node in C++ (rcl), layers from localization.cpp.layers\n");
    std::fflush(stdout);

    ros::RclWaitSet wait_set(&context.get(), 3, 1);
    while (!stopping) {
      rcl_wait_set_t* set = wait_set.get();
      ros::detail::check(rcl_wait_set_clear(set), "wait set");
      ros::detail::check(rcl_wait_set_add_subscription(set, localization.imu().get(), nullptr),
                         "wait set");
      ros::detail::check(
          rcl_wait_set_add_subscription(set, localization.wheels().get(), nullptr), "wait set");
      ros::detail::check(rcl_wait_set_add_subscription(set, localization.gps().get(), nullptr),
                         "wait set");
      ros::detail::check(rcl_wait_set_add_guard_condition(set, stop.get(), nullptr), "wait set");
      const rcl_ret_t waited = rcl_wait(set, RCL_S_TO_NS(1));
      if (waited == RCL_RET_TIMEOUT) continue;
      ros::detail::check(waited, "rcl_wait");
      // Wheels and GPS first: the gyro reading uses the latest of both.
      if (set->subscriptions[1] != nullptr) localization.on_wheels();
      if (set->subscriptions[2] != nullptr) localization.on_gps();
      if (set->subscriptions[0] != nullptr) localization.on_gyro();
    }
  } catch (const std::exception& error) {
    std::fprintf(stderr, "localization: %s\n", error.what());
    return 1;
  }
  return 0;  // the ContextNode said it leaves, then the node and the context went
}
