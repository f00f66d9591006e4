// Threads: scoped activation per thread, critical sections deferring switches made from
// other threads, and calls that never see a half-applied configuration.
#include <gtest/gtest.h>

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "contextros/contextros.hpp"
#include "fixtures.hpp"

using contextros::SwitchOutcome;
using contextros::SwitchStatus;

namespace {

using Chain = contextros::ProceedOf<std::string()>;
std::string chain_base(Chain) { return "base"; }
std::string chain_X(Chain proceed) { return "X>" + proceed(); }
std::string chain_Y(Chain proceed) { return "Y>" + proceed(); }
std::string chain_Z(Chain proceed) { return "Z>" + proceed(); }
contextros::LayeredOf<std::string()> chain_layered{
    "chain", &chain_base, {{"ThrX", &chain_X}, {"ThrY", &chain_Y}, {"ThrZ", &chain_Z}}};
std::string chain() { return chain_layered.invoke(nullptr); }

// A one-shot signal between two threads.
class Signal {
 public:
  void set() {
    std::lock_guard<std::mutex> lock(mutex_);
    set_ = true;
    changed_.notify_all();
  }
  void wait() {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [this] { return set_; });
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  bool set_ = false;
};

class Threads : public RuntimeTest {};

TEST_F(Threads, ScopedActivationIsPerThread) {
  Signal entered, checked;
  std::string inside, other;
  std::thread scoped([&] {
    contextros::ScopedActivation x("ThrX");
    inside = chain();
    entered.set();
    checked.wait();
  });
  entered.wait();
  other = chain();
  checked.set();
  scoped.join();
  EXPECT_EQ(inside, "X>base");
  EXPECT_EQ(other, "base");
  EXPECT_EQ(chain(), "base");
}

TEST_F(Threads, ScopesNestOnTopOfTheDecisiveConfiguration) {
  contextros::activate("ThrX");
  {
    contextros::ScopedActivation y("ThrY");
    EXPECT_EQ(chain(), "Y>X>base");
    EXPECT_EQ(contextros::effective_layers(), (Names{"ThrX", "ThrY"}));
    EXPECT_EQ(contextros::active_layers(), (Names{"ThrX"}));
    {
      contextros::ScopedDeactivation not_x("ThrX");
      EXPECT_EQ(chain(), "Y>base");
    }
    // A decisive switch made meanwhile shows through the scope.
    contextros::activate("ThrZ");
    EXPECT_EQ(chain(), "Y>Z>X>base");
  }
  EXPECT_EQ(chain(), "Z>X>base");
}

TEST_F(Threads, AScopedThreadSeesEveryDecisiveSwitchAtItsNextCall) {
  Signal first, switched, second;
  std::string before, after;
  std::thread scoped([&] {
    contextros::ScopedActivation y("ThrY");
    before = chain();
    first.set();
    switched.wait();
    after = chain();
    second.set();
  });
  first.wait();
  contextros::activate("ThrX");  // another thread's decisive switch
  switched.set();
  second.wait();
  scoped.join();
  EXPECT_EQ(before, "Y>base");
  EXPECT_EQ(after, "Y>X>base");
}

// The thread's cache of the last head it used must not outlive a change of its scopes,
// whoever refreshes the thread's configuration first.
TEST_F(Threads, ANewScopeIsSeenAfterTheThreadsLayersWereAskedFor) {
  contextros::ScopedActivation x("ThrX");
  EXPECT_EQ(chain(), "X>base");
  contextros::ScopedActivation y("ThrY");
  EXPECT_EQ(contextros::effective_layers(), (Names{"ThrX", "ThrY"}));
  EXPECT_EQ(chain(), "Y>X>base");
}

TEST_F(Threads, ScopedActivationChecksRelations) {
  contextros::define_layer({"ThrLonely", {"ThrX"}, {}, {}, ""});
  contextros::activate("ThrX");
  EXPECT_THROW(contextros::ScopedActivation("ThrLonely"), contextros::RelationError);
  EXPECT_EQ(chain(), "X>base");
}

TEST_F(Threads, CriticalSectionDefersSwitchesFromOtherThreads) {
  Signal opened, requested;
  std::thread::id settled_on;
  SwitchOutcome settled{SwitchStatus::deferred, 0, ""};
  int calls = 0;
  std::string during;
  std::thread holder([&] {
    contextros::CriticalSection section;
    opened.set();
    requested.wait();
    during = chain();
  });  // the section closes here, on `holder`
  opened.wait();
  EXPECT_TRUE(contextros::in_critical_section());
  const auto outcome = contextros::set_active({"ThrX"}, [&](const SwitchOutcome& result) {
    ++calls;
    settled = result;
    settled_on = std::this_thread::get_id();
  });
  EXPECT_EQ(outcome.status, SwitchStatus::deferred);
  EXPECT_EQ(calls, 0);
  EXPECT_TRUE(contextros::active_layers().empty());
  const auto holder_id = holder.get_id();
  requested.set();
  holder.join();
  EXPECT_EQ(during, "base");
  EXPECT_FALSE(contextros::in_critical_section());
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(settled.status, SwitchStatus::applied);
  EXPECT_EQ(settled.epoch, contextros::current_epoch());
  EXPECT_EQ(settled_on, holder_id);
  EXPECT_EQ(chain(), "X>base");
}

TEST_F(Threads, DeferredSwitchesApplyInOrderWhenTheLastSectionCloses) {
  contextros::define_layer({"ThrNeedsY", {}, {"ThrY"}, {}, ""});
  std::vector<SwitchStatus> results;
  auto record = [&](const SwitchOutcome& outcome) { results.push_back(outcome.status); };
  {
    contextros::CriticalSection outer;
    {
      contextros::CriticalSection inner;
      contextros::activate("ThrY", record);
    }
    EXPECT_TRUE(results.empty());  // the outer section is still open
    contextros::deactivate("ThrY", record);
    contextros::activate("ThrNeedsY", record);  // invalid by the time it applies
    contextros::activate("ThrZ", record);
  }
  EXPECT_EQ(results, (std::vector<SwitchStatus>{SwitchStatus::applied, SwitchStatus::applied,
                                                SwitchStatus::failed, SwitchStatus::applied}));
  EXPECT_EQ(contextros::active_layers(), (Names{"ThrZ"}));
}

// While one thread switches among configurations as fast as it can, callers (some inside a
// scoped activation) must only ever see the complete chain of one configuration.
TEST_F(Threads, CallsNeverSeeAMixedChain) {
  const std::vector<Names> configurations = {
      {}, {"ThrX"}, {"ThrX", "ThrY", "ThrZ"}, {"ThrZ", "ThrY", "ThrX"}, {"ThrY", "ThrX"}};
  // The chains of those configurations, and of each with ThrZ scoped on top.
  const std::set<std::string> valid = {"base", "X>base", "Z>Y>X>base", "X>Y>Z>base", "X>Y>base"};
  const std::set<std::string> valid_scoped = {"Z>base", "Z>X>base", "Z>Y>X>base", "X>Y>Z>base",
                                              "Z>X>Y>base"};
  std::atomic<bool> stop{false};
  std::atomic<long> calls{0};
  std::vector<std::string> bad;
  std::mutex bad_mutex;
  auto caller = [&](bool scoped) {
    std::unique_ptr<contextros::ScopedActivation> scope;
    if (scoped) scope = std::make_unique<contextros::ScopedActivation>("ThrZ");
    while (!stop.load()) {
      std::string seen = chain();
      calls.fetch_add(1);
      if ((scoped ? valid_scoped : valid).count(seen) == 0) {
        std::lock_guard<std::mutex> lock(bad_mutex);
        bad.push_back(seen);
      }
    }
  };
  std::vector<std::thread> callers;
  callers.emplace_back(caller, false);
  callers.emplace_back(caller, true);
  while (calls.load() < 1000) std::this_thread::yield();  // both callers are running
  for (int round = 0; round < 20000; ++round) {
    contextros::set_active(configurations[round % configurations.size()]);
  }
  stop.store(true);
  for (auto& thread : callers) thread.join();
  EXPECT_TRUE(bad.empty()) << bad.size() << " mixed chains, e.g. " << (bad.empty() ? "" : bad[0]);
  EXPECT_GT(calls.load(), 0);
}

// The direct path (no scope anywhere): a call loads only its head's code, and the head's
// proceed finds its chain later. Switching among configurations that share a head but not
// the rest, callers must still see the complete chain of one configuration.
TEST_F(Threads, DirectCallsNeverSeeAMixedChainWhenTheHeadStaysAndTheRestChanges) {
  const std::vector<Names> configurations = {
      {"ThrX", "ThrY"}, {"ThrY"}, {"ThrZ", "ThrX", "ThrY"}, {"ThrX", "ThrZ"}, {"ThrY", "ThrX"}};
  const std::set<std::string> valid = {"Y>X>base", "Y>base", "Y>X>Z>base", "Z>X>base",
                                       "X>Y>base"};
  std::atomic<bool> stop{false};
  std::atomic<long> calls{0};
  std::vector<std::string> bad;
  std::mutex bad_mutex;
  auto caller = [&] {
    while (!stop.load()) {
      std::string seen = chain();
      calls.fetch_add(1);
      if (valid.count(seen) == 0) {
        std::lock_guard<std::mutex> lock(bad_mutex);
        bad.push_back(seen);
      }
    }
  };
  contextros::set_active(configurations[0]);
  std::vector<std::thread> callers;
  callers.emplace_back(caller);
  callers.emplace_back(caller);
  while (calls.load() < 1000) std::this_thread::yield();
  for (int round = 0; round < 20000; ++round) {
    contextros::set_active(configurations[round % configurations.size()]);
  }
  stop.store(true);
  for (auto& thread : callers) thread.join();
  EXPECT_TRUE(bad.empty()) << bad.size() << " mixed chains, e.g. " << (bad.empty() ? "" : bad[0]);
}

}  // namespace
