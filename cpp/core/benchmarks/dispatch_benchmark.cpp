// C++ dispatch benchmark: a layered call (code generated from dispatch.cpp.layers) against
// a plain out-of-line call and Listing 2's if/else dispatch, with 0, 1 and 3 active layers,
// with and without proceed. Prints one line per case:
//   case<TAB>ns per call (fastest round)<TAB>x plain (median over rounds)
// Every case is measured in the same short interleaved rounds, and its ratio to the plain call
// taken within each round: on a shared machine the load and the clock change between rounds,
// not within one. Each call depends on the previous result, so calls cannot overlap.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "baselines.hpp"
#include "contextros/contextros.hpp"
#include "dispatch.layers.hpp"

namespace {

using Clock = std::chrono::steady_clock;

using Timer = double (*)(long iterations);

struct Case {
  std::string name;
  std::vector<std::string> layers;  // the configuration, for both dispatch styles
  Timer time;
  double best;
  std::vector<double> ratios;
  // How the layers are active: decisively, by a ScopedActivation of the timing thread, for
  // the called object only (activate_for), or decisively while another object has layers of
  // its own: ones the method has no partial for, or ones that change its chain.
  enum class Mode { decisive, scoped, object, other_object, other_object_refining } mode =
      Mode::decisive;
};

BenchCounter counter, other_counter;
baseline::Counter plain_counter;
// A method call, through a plain function as the other cases are.
int method_call(int x) { return counter.add(x); }
int plain_method_call(int x) { return plain_counter.add(x); }


// A loop calling F directly, as a program calls a function (no call through a pointer).
template <int (*F)(int)>
double time_loop(long iterations) {
  int x = 0;
  const auto start = Clock::now();
  for (long i = 0; i < iterations; ++i) {
    x = F(x) & 0xffff;
    asm volatile("" : "+r"(x));  // no vectorising or folding of the loop
  }
  const auto elapsed = std::chrono::duration<double, std::nano>(Clock::now() - start).count();
  if (x == -1) std::puts("");  // keeps the result alive
  return elapsed / static_cast<double>(iterations);
}

void configure(const std::vector<std::string>& layers) {
  contextros::set_active(layers);
  auto on = [&](const char* name) {
    return std::find(layers.begin(), layers.end(), name) != layers.end();
  };
  baseline::set_active(on("BenchL1"), on("BenchL2"), on("BenchL3"));
}

}  // namespace

int main(int argc, char** argv) {
  const long iterations = argc > 1 ? std::atol(argv[1]) : 200'000;
  const int rounds = argc > 2 ? std::atoi(argv[2]) : 101;
  const std::vector<std::string> none, one{"BenchL1"}, three{"BenchL1", "BenchL2", "BenchL3"};
  std::vector<Case> cases = {
      {"plain out-of-line call", none, &time_loop<&baseline::plain>, {}, {}},
      {"layered: no active layer", none, &time_loop<&step>, {}, {}},
      {"layered: one partial, no proceed", one, &time_loop<&single>, {}, {}},
      {"atomic function pointer: one partial, no proceed", one,
       &time_loop<&baseline::pointer_call>, {}, {}},
      {"atomic function pointer, callee taking a proceed: one partial, no proceed", one,
       &time_loop<&baseline::pointer_call_with_proceed>, {}, {}},
      {"two dependent loads (before issue 18): one partial, no proceed", one,
       &time_loop<&baseline::two_loads_call>, {}, {}},
      {"layered: one partial, proceeds", one, &time_loop<&step>, {}, {}},
      {"layered: three partials, proceed", three, &time_loop<&step>, {}, {}},
      {"layered: one partial, no proceed, scoped (ScopedActivation)", one, &time_loop<&single>,
       {}, {}, Case::Mode::scoped},
      {"plain member call", none, &time_loop<&plain_method_call>, {}, {}},
      {"layered method: one partial, no proceed", one, &time_loop<&method_call>, {}, {}},
      {"layered method: one partial, another object with layers of its own", one,
       &time_loop<&method_call>, {}, {}, Case::Mode::other_object},
      {"layered method: one partial, for the object (activate_for)", one,
       &time_loop<&method_call>, {}, {}, Case::Mode::object},
      {"layered method: one partial, another object whose own layers change its chain", one,
       &time_loop<&method_call>, {}, {}, Case::Mode::other_object_refining},
      {"if/else (Listing 2): no active layer", none, &time_loop<&baseline::if_else_step>, {}, {}},
      {"if/else (Listing 2): one partial, no proceed", one, &time_loop<&baseline::if_else_single>, {}, {}},
      {"if/else (Listing 2): one partial, proceeds", one, &time_loop<&baseline::if_else_step>, {}, {}},
      {"if/else (Listing 2): three partials, proceed", three, &time_loop<&baseline::if_else_step>, {}, {}},
  };
  for (int round = 0; round < rounds; ++round) {
    std::vector<double> costs;
    for (auto& item : cases) {
      std::optional<contextros::ScopedActivation> scope;
      if (item.mode == Case::Mode::scoped) {
        configure({});
        scope.emplace(item.layers.front());
      } else if (item.mode == Case::Mode::object) {
        configure({});
        contextros::activate_for(counter, item.layers.front());
      } else {
        configure(item.layers);
        if (item.mode == Case::Mode::other_object) {
          contextros::activate_for(other_counter, "BenchL2");
        } else if (item.mode == Case::Mode::other_object_refining) {
          contextros::deactivate_for(other_counter, "BenchL1");
        }
      }
      const double cost = item.time(iterations);
      contextros::reset_for(counter);
      contextros::reset_for(other_counter);
      item.best = round == 0 ? cost : std::min(item.best, cost);
      costs.push_back(cost);
    }
    for (std::size_t i = 0; i < cases.size(); ++i) cases[i].ratios.push_back(costs[i] / costs[0]);
  }
  for (auto& item : cases) {
    std::sort(item.ratios.begin(), item.ratios.end());
    std::printf("%s\t%.3f\t%.3f\n", item.name.c_str(), item.best,
                item.ratios[item.ratios.size() / 2]);
  }
  return 0;
}
