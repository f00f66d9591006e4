// A layered function destroyed while another thread switches: the runtime must not rewire()
// it once its destruction began (once ~Layered ran, rewire() is a pure virtual call on
// destroyed members: the program terminates).
#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <memory>
#include <string>
#include <thread>

#include "contextros/contextros.hpp"

namespace {

using Proceed = contextros::ProceedOf<std::string()>;
std::string base(Proceed) { return "base"; }
std::string in_teardown_a(Proceed proceed) { return "A>" + proceed(); }
std::string in_teardown_b(Proceed proceed) { return "B>" + proceed(); }

TEST(Teardown, ASwitchDoesNotRewireALayeredFunctionBeingDestroyed) {
  using namespace std::chrono_literals;
  contextros::define_layer({"TeardownA", {}, {}, {}, {}});
  contextros::define_layer({"TeardownB", {}, {}, {}, {}});
  contextros::set_active({});
  auto function = std::make_unique<contextros::LayeredOf<std::string()>>(
      "teardown", &base,
      std::initializer_list<contextros::LayeredOf<std::string()>::Partial>{
          {"TeardownA", &in_teardown_a},
          {"TeardownB", &in_teardown_b}});
  ASSERT_EQ(function->invoke(nullptr), "base");
  std::promise<void> holding;
  std::promise<void> destroying;
  std::shared_future<void> destroying_started = destroying.get_future().share();
  bool once = false;
  // Holds the runtime's lock (an observer runs inside the switch) while `function` is being
  // destroyed on another thread, then switches again from the observer (rewires).
  contextros::Subscription hold = contextros::subscribe([&](const contextros::SwitchEvent&) {
    if (once) return;
    once = true;
    holding.set_value();
    destroying_started.wait();
    std::this_thread::sleep_for(200ms);  // lets the destructor run up to the runtime's lock
    contextros::set_active({"TeardownB"});
  });
  std::thread switcher([] { contextros::set_active({"TeardownA"}); });
  holding.get_future().wait();
  std::thread destroyer([&] {
    destroying.set_value();
    function.reset();
  });
  switcher.join();
  destroyer.join();
  EXPECT_EQ(contextros::active_layers(), std::vector<std::string>{"TeardownB"});
}

}  // namespace
