// The rcl adapter (Participant, ContextNode) in one process: a test node plays the manager
// on the participant's topics, under a namespace of its own (no other test hears it).
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <contextros/contextros.hpp>
#include <contextros/ros/participant.hpp>
#include <contextros/ros/rcl_handles.hpp>
#include <contextros/ros/rcl_node.hpp>
#include <contextros/ros/topics.hpp>
#include <contextros_interfaces/msg/layer_state.hpp>
#include <future>
#include <memory>
#include <string>
#include <thread>
#include <vector>

namespace {

using namespace std::chrono_literals;
using contextros::ros::ContextNode;
using contextros::ros::Participant;
using contextros::ros::RclContext;
using contextros::ros::RclNode;
using contextros::ros::RclPublisher;
using contextros::ros::RclSubscription;
using contextros::ros::RclWaitSet;
using contextros::ros::type_support;
using StateMessage = contextros_interfaces::msg::LayerState;

std::string test_namespace() { return "/adapter_test_" + std::to_string(::getpid()); }

StateMessage state(std::uint64_t epoch, std::vector<std::string> layers) {
  StateMessage message;
  message.epoch = epoch;
  message.active_layers = std::move(layers);
  message.manager_id = "test-manager";
  message.requester = "test";
  return message;
}

// Polls `done` until it holds or 10 s passed.
template <class Predicate>
bool eventually(Predicate done) {
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(5ms);
  }
  return true;
}

// The manager's side: publishes states and heartbeats; probes see what was delivered.
struct FakeManager {
  explicit FakeManager(RclContext& context)
      : node(context, "fake_manager", test_namespace()),
        states(node.get(), type_support<StateMessage>(), contextros::ros::state_topic,
               contextros::ros::state_qos()),
        heartbeats(node.get(), type_support<StateMessage>(), contextros::ros::heartbeat_topic,
                   contextros::ros::heartbeat_qos()),
        state_probe(node.get(), type_support<StateMessage>(), contextros::ros::state_topic,
                    contextros::ros::state_qos()),
        heartbeat_probe(node.get(), type_support<StateMessage>(),
                        contextros::ros::heartbeat_topic, contextros::ros::heartbeat_qos()),
        wait_set(&context.get(), 2, 0) {}

  // Waits until each probe received one message with this epoch (the participant's
  // subscriptions, matched as long, have them too by then, as a rule).
  bool delivered(std::uint64_t state_epoch, std::uint64_t heartbeat_epoch) {
    bool state_seen = false;
    bool heartbeat_seen = false;
    return eventually([&] {
      rcl_wait_set_t* set = wait_set.get();
      if (rcl_wait_set_clear(set) != RCL_RET_OK ||
          rcl_wait_set_add_subscription(set, state_probe.get(), nullptr) != RCL_RET_OK ||
          rcl_wait_set_add_subscription(set, heartbeat_probe.get(), nullptr) != RCL_RET_OK ||
          rcl_wait(set, RCL_MS_TO_NS(5)) != RCL_RET_OK) {
        rcl_reset_error();
      }
      StateMessage message;
      while (state_probe.take(message)) state_seen |= message.epoch == state_epoch;
      while (heartbeat_probe.take(message)) heartbeat_seen |= message.epoch == heartbeat_epoch;
      return state_seen && heartbeat_seen;
    });
  }

  // Both the probe and the participant hear the heartbeats.
  bool heartbeats_matched() {
    return eventually([&] {
      std::size_t count = 0;
      return rcl_publisher_get_subscription_count(heartbeats.get(), &count) == RCL_RET_OK &&
             count >= 2;
    });
  }

  RclNode node;
  RclPublisher states;
  RclPublisher heartbeats;
  RclSubscription state_probe;
  RclSubscription heartbeat_probe;
  RclWaitSet wait_set;
};

class ParticipantAdapter : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    for (const char* name : {"AdapterA", "AdapterB", "AdapterC"}) {
      contextros::define_layer(contextros::LayerInfo{name, {}, {}, {}, {}});
    }
  }
  void SetUp() override { contextros::set_active({}); }

  RclContext context{0, nullptr};
};

// Item: a state and an older heartbeat taken in one wake-up. The newer one must stay applied
// (the older one was stale once the newer one was applied; the runtime must not run it).
TEST_F(ParticipantAdapter, AnOlderHeartbeatInTheSameWakeUpIsNotApplied) {
  FakeManager manager(context);
  RclNode follower(context, "follower", test_namespace());
  std::promise<void> entered;
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  Participant participant(follower.get(), {std::vector<std::string>{}});
  // Holds the participant's thread after epoch 4 while the next two arrive.
  participant.add_listener([&](const contextros::ros::LayerState& applied) {
    if (applied.epoch == 4) {
      entered.set_value();
      released.wait();
    }
  });
  manager.states.publish(state(4, {"AdapterA"}));
  ASSERT_EQ(entered.get_future().wait_for(10s), std::future_status::ready);
  ASSERT_TRUE(manager.heartbeats_matched());
  manager.states.publish(state(6, {"AdapterC"}));
  manager.heartbeats.publish(state(5, {"AdapterB"}));
  ASSERT_TRUE(manager.delivered(6, 5));
  release.set_value();
  ASSERT_TRUE(eventually([&] { return participant.applied_epoch() == 6; }));
  EXPECT_EQ(contextros::active_layers(), std::vector<std::string>{"AdapterC"});
}

}  // namespace

namespace {

// Fails the whole program rather than hang when `done` never comes (a deadlock).
void within_10_s(std::future<void>& done, const char* what) {
  if (done.wait_for(10s) != std::future_status::ready) {
    std::fprintf(stderr, "deadlock: %s\n", what);
    std::_Exit(1);
  }
}

// An observer runs on the switching thread; asking the participant must not deadlock.
TEST_F(ParticipantAdapter, AnObserverMayAskTheParticipant) {
  FakeManager manager(context);
  RclNode follower(context, "follower", test_namespace());
  Participant participant(follower.get(), {std::vector<std::string>{}});
  std::promise<void> asked;
  bool once = false;
  contextros::Subscription ask = contextros::subscribe([&](const contextros::SwitchEvent&) {
    if (!once) {
      once = true;
      (void)participant.applied_epoch();
      asked.set_value();
    }
  });
  manager.states.publish(state(7, {"AdapterB"}));
  std::future<void> done = asked.get_future();
  within_10_s(done, "an observer asked Participant::applied_epoch()");
  EXPECT_TRUE(eventually([&] { return participant.applied_epoch() == 7; }));
}

// A listener may ask who carries the participant, and may destroy its own ContextNode: the
// next node takes over.
TEST_F(ParticipantAdapter, AListenerMayDestroyItsOwnContextNode) {
  FakeManager manager(context);
  RclNode first_node(context, "first", test_namespace());
  RclNode second_node(context, "second", test_namespace());
  // Shared with the listener, which stays registered with the process after this test.
  struct Drop {
    std::unique_ptr<ContextNode> first;
    std::string first_name;
    std::promise<void> dropped;
  };
  auto drop = std::make_shared<Drop>();
  drop->first = std::make_unique<ContextNode>(first_node.get());
  drop->first_name = first_node.fully_qualified_name();
  ContextNode second(second_node.get());
  ContextNode::add_listener([drop](const contextros::ros::LayerState&) {
    if (drop->first && ContextNode::carrier() == drop->first_name) {
      drop->first.reset();
      drop->dropped.set_value();
    }
  });
  manager.states.publish(state(8, {"AdapterC"}));
  std::future<void> done = drop->dropped.get_future();
  within_10_s(done, "a listener destroyed its own ContextNode");
  EXPECT_TRUE(eventually([&] { return ContextNode::carrier() == second_node.fully_qualified_name(); }));
}

}  // namespace

namespace {

// Whatever a listener throws, the participant goes on.
TEST_F(ParticipantAdapter, AListenerThrowingAnythingDoesNotStopTheParticipant) {
  FakeManager manager(context);
  RclNode follower(context, "follower", test_namespace());
  Participant participant(follower.get(), {std::vector<std::string>{}});
  participant.add_listener([](const contextros::ros::LayerState& applied) {
    if (applied.epoch == 9) throw 42;
  });
  manager.states.publish(state(9, {"AdapterA"}));
  ASSERT_TRUE(eventually([&] { return participant.applied_epoch() == 9; }));
  manager.states.publish(state(10, {"AdapterB"}));
  EXPECT_TRUE(eventually([&] { return participant.applied_epoch() == 10; }));
}

}  // namespace

namespace {

// A safe configuration set while the manager was lost gives way to the applied state when
// the manager is back with the same epoch (its heartbeat is not newer than what was applied).
TEST_F(ParticipantAdapter, TheAppliedStateReturnsWhenTheManagerIsBack) {
  FakeManager manager(context);
  RclNode follower(context, "follower", test_namespace());
  contextros::ros::ParticipantOptions options;
  options.layers = std::vector<std::string>{};
  options.manager_timeout = 300ms;
  Participant participant(follower.get(), options);
  std::atomic<int> lost{0};
  std::atomic<int> found{0};
  participant.add_manager_listener([&](bool is_lost) {
    if (is_lost) {
      contextros::set_active({"AdapterB"});  // the safe fallback
      ++lost;
    } else {
      ++found;
    }
  });
  manager.states.publish(state(11, {"AdapterA"}));
  ASSERT_TRUE(eventually([&] { return participant.applied_epoch() == 11; }));
  ASSERT_TRUE(eventually([&] { return lost.load() == 1; }));
  EXPECT_EQ(contextros::active_layers(), std::vector<std::string>{"AdapterB"});
  ASSERT_TRUE(manager.heartbeats_matched());
  ASSERT_TRUE(eventually([&] {
    manager.heartbeats.publish(state(11, {"AdapterA"}));  // best effort: until heard
    return found.load() > 0;
  }));
  EXPECT_TRUE(eventually([&] {
    return contextros::active_layers() == std::vector<std::string>{"AdapterA"};
  }));
  EXPECT_EQ(participant.applied_epoch(), 11u);
}

}  // namespace

namespace {

// While another thread destroys the carrying ContextNode, a listener running on the
// participant's thread asks who carries it: the destructor must not hold the process's lock
// while it waits for that thread.
TEST_F(ParticipantAdapter, AListenerMayAskForTheCarrierWhileItsNodeIsDestroyed) {
  FakeManager manager(context);
  RclNode first_node(context, "first_c", test_namespace());
  auto first = std::make_unique<ContextNode>(first_node.get());
  struct Shared {
    std::promise<void> entered;
    std::promise<void> destroying;
    std::promise<void> asked;
    bool armed = true;
  };
  auto shared = std::make_shared<Shared>();
  std::shared_future<void> destroying = shared->destroying.get_future().share();
  ContextNode::add_listener([shared, destroying](const contextros::ros::LayerState&) {
    if (!shared->armed) return;
    shared->armed = false;
    shared->entered.set_value();
    destroying.wait();
    std::this_thread::sleep_for(100ms);  // lets the destructor take the process's lock
    (void)ContextNode::carrier();
    shared->asked.set_value();
  });
  manager.states.publish(state(12, {"AdapterA"}));
  std::future<void> entered = shared->entered.get_future();
  within_10_s(entered, "the listener was not called");
  std::thread destroyer([&] {
    shared->destroying.set_value();
    first.reset();
  });
  std::future<void> asked = shared->asked.get_future();
  within_10_s(asked, "a listener asked for the carrier while its node was destroyed");
  destroyer.join();
  EXPECT_EQ(ContextNode::carrier(), "");
}

}  // namespace
