// The process-wide runtime: layer definitions, the decisive configuration and its epoch,
// critical sections, observers, per-thread scopes and the layered functions to rewire.
//
// One recursive lock serialises switches (observers may switch again from their callback, as
// in the Python core); calls on the fast path never take it.

#include <algorithm>
#include <atomic>
#include <deque>
#include <map>
#include <mutex>
#include <utility>

#include "configuration.hpp"
#include "contextros/activation.hpp"
#include "contextros/errors.hpp"
#include "contextros/layer.hpp"
#include "contextros/layered.hpp"

namespace contextros {
namespace detail {
namespace {

using Plan = std::function<Configuration(const Configuration&)>;

struct Pending {
  Plan plan;
  SwitchCallback on_settled;
};

struct Settled {
  SwitchCallback on_settled;
  SwitchOutcome outcome;
};

// The scoped activations of the calling thread, and the chain heads composed for them (and
// for the objects with layers of their own it called methods on).
struct ThreadScopes {
  std::vector<Step> steps;
  std::uint64_t generation = 0;  // of `effective`; 0 = stale
  Configuration effective;
  struct Cached {
    std::uint64_t generation;
    const void* head;
  };
  // By function and receiver (null for none); valid for `generation` only.
  std::map<std::pair<const LayeredBase*, const void*>, Cached> heads;
  // The last of them: a loop calling one function on one object finds it here.
  std::pair<const LayeredBase*, const void*> last_key{nullptr, nullptr};
  Cached last{0, nullptr};
};

thread_local ThreadScopes thread_scopes;

std::vector<std::string> checked_names(const std::vector<std::string>& names) {
  for (const auto& name : names) {
    if (!is_identifier(name)) {
      throw LayerDefinitionError("'" + name + "' is not a layer name (an identifier)");
    }
  }
  return names;
}

class Runtime {
 public:
  static Runtime& instance() {
    static Runtime runtime;
    return runtime;
  }

  std::recursive_mutex mutex;
  std::map<std::string, LayerInfo> layers;
  // What define_layer was given beyond the relations, by layer name.
  struct Details {
    std::string description;
    LayerHooks hooks;
  };
  std::map<std::string, Details> details;
  Configuration active;
  std::uint64_t epoch = 0;
  // Bumped on every change of the decisive configuration or the layer definitions: thread
  // scopes recompute then. Read without the lock by the scoped call path.
  std::atomic<std::uint64_t> generation{1};
  std::vector<LayeredBase*> functions;
  std::atomic<int> critical_depth{0};
  std::deque<Pending> deferred;
  std::map<std::uint64_t, std::function<void(const SwitchEvent&)>> observers;
  std::uint64_t next_observer = 1;
  int live_scopes = 0;
  // The objects with layers of their own (activate_for), by address: their steps, replayed
  // on the decisive configuration.
  std::map<const void*, std::vector<Step>> receivers;

  Definitions definitions() {
    return [this](const std::string& name) {
      auto found = layers.find(name);
      return found != layers.end() ? found->second : LayerInfo{name, {}, {}, {}, {}};
    };
  }

  void rewire_all() {
    const LayeredBase::Levels levels = receiver_levels();
    for (LayeredBase* function : functions) function->rewire(active, live_scopes > 0, levels);
  }

  // What a call on each object with layers of its own runs, without scopes (lock held).
  LayeredBase::Levels receiver_levels() {
    LayeredBase::Levels levels;
    levels.reserve(receivers.size());
    for (const auto& item : receivers) levels.emplace_back(item.first, object_level(item.first));
    return levels;
  }

  // Applies `plan` now (lock held); the outcome says what became of it.
  SwitchOutcome apply(const Plan& plan) {
    Configuration next;
    try {
      next = plan(active);
    } catch (const LayerError& error) {
      return {SwitchStatus::failed, epoch, error.what()};
    }
    if (next == active) return {SwitchStatus::applied, epoch, ""};
    std::vector<std::string> leaving;
    for (auto layer = active.rbegin(); layer != active.rend(); ++layer) {
      if (std::find(next.begin(), next.end(), *layer) == next.end()) leaving.push_back(*layer);
    }
    for (const auto& layer : leaving) {
      try {
        run_hook(layer, false);
      } catch (const HookError& error) {  // abandons the switch: nothing changed
        return {SwitchStatus::failed, epoch, error.what()};
      }
    }
    std::vector<std::string> arriving;
    for (const auto& layer : next) {
      if (std::find(active.begin(), active.end(), layer) == active.end()) arriving.push_back(layer);
    }
    SwitchEvent event{epoch + 1, active, next};
    active = std::move(next);
    ++epoch;
    ++generation;
    rewire_all();
    std::string failure;  // the first failing on_activate; the others still run
    for (const auto& layer : arriving) {
      try {
        run_hook(layer, true);
      } catch (const HookError& error) {
        if (failure.empty()) failure = error.what();
      }
    }
    // Copied: an observer may unsubscribe (itself or another) from its callback.
    auto current = observers;
    for (auto& [id, observer] : current) {
      try {
        observer(event);
      } catch (...) {  // a failing observer must not undo or block the switch
      }
    }
    return {SwitchStatus::applied, epoch, failure};
  }

  // Runs a layer's on_activate (or on_deactivate) hook, if it has one; HookError if it throws.
  void run_hook(const std::string& layer, bool activating) {
    auto found = details.find(layer);
    if (found == details.end()) return;
    // A copy: the hook may redefine its own layer.
    const std::function<void()> hook =
        activating ? found->second.hooks.on_activate : found->second.hooks.on_deactivate;
    if (!hook) return;
    const std::string kind = activating ? "on_activate" : "on_deactivate";
    try {
      hook();
    } catch (const std::exception& error) {
      throw HookError(kind + " hook of layer " + layer + " failed: " + error.what(), layer);
    } catch (...) {
      throw HookError(kind + " hook of layer " + layer + " failed (a non-standard exception)",
                      layer);
    }
  }

  SwitchOutcome request(Plan plan, SwitchCallback on_settled) {
    SwitchOutcome outcome;
    {
      std::lock_guard<std::recursive_mutex> lock(mutex);
      if (critical_depth.load() > 0) {
        deferred.push_back({std::move(plan), std::move(on_settled)});
        return {SwitchStatus::deferred, epoch, ""};
      }
      outcome = apply(plan);
    }
    if (on_settled) on_settled(outcome);
    return outcome;
  }

  // The thread's configuration (lock held), recomputed when stale.
  const Configuration& effective(ThreadScopes& scopes) {
    const std::uint64_t now = generation.load();
    if (scopes.generation != now) {
      scopes.effective = replay(active, scopes.steps, definitions());
      scopes.generation = now;
      scopes.heads.clear();
      scopes.last = {0, nullptr};
    }
    return scopes.effective;
  }

  // The decisive configuration with `receiver`'s own layers (lock held). A level that would
  // break a relation with the decisive configuration is suspended: skipped for as long as
  // the conflict lasts (a decisive switch is never refused because of an object).
  Configuration object_level(const void* receiver) {
    auto found = receiver ? receivers.find(receiver) : receivers.end();
    if (found == receivers.end()) return active;
    Configuration candidate = replay(active, found->second, definitions());
    try {
      validate(candidate, definitions());
    } catch (const RelationError&) {
      return active;
    }
    return candidate;
  }

  // What a call on `receiver` runs in this thread: its level, then the thread's scopes.
  Configuration effective_for(ThreadScopes& scopes, const void* receiver) {
    if (!receiver || !receivers.count(receiver)) return effective(scopes);
    return replay(object_level(receiver), scopes.steps, definitions());
  }

  // Adds steps to `receiver`'s level, validated first (RelationError: nothing changed).
  void add_steps(const void* receiver, const std::vector<std::string>& layers, bool activating) {
    std::vector<Step> steps = receivers.count(receiver) ? receivers[receiver] : std::vector<Step>{};
    if (!steps.empty()) {
      try {
        validate(replay(active, steps, definitions()), definitions());
      } catch (const RelationError& error) {
        throw RelationError("this object's own layers are suspended (" + std::string(error.what()) +
                                "): reset_for() it before changing them",
                            error.layers());
      }
    }
    for (const auto& name : checked_names(layers)) steps.push_back({activating, name});
    Configuration candidate = replay(active, steps, definitions());
    try {
      validate(candidate, definitions());
    } catch (const RelationError& error) {
      throw RelationError(std::string(error.what()) + ", for this object", error.layers());
    }
    receivers[receiver] = std::move(steps);
    ++generation;
    rewire_all();
  }
};

}  // namespace

LayeredBase::~LayeredBase() { unenroll(); }

void LayeredBase::unenroll() noexcept {
  if (!enrolled_) return;  // set and cleared by the owning thread only
  Runtime& runtime = Runtime::instance();
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  enrolled_ = false;
  auto& functions = runtime.functions;
  functions.erase(std::remove(functions.begin(), functions.end(), this), functions.end());
  ++runtime.generation;  // no thread's cache may hand out this function's chains again
}

void LayeredBase::enroll() {
  Runtime& runtime = Runtime::instance();
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  runtime.functions.push_back(this);
  enrolled_ = true;
  rewire(runtime.active, runtime.live_scopes > 0, runtime.receiver_levels());
}

const void* scoped_head(const LayeredBase& function, const void* decisive, Compose compose,
                        const void* receiver) {
  ThreadScopes& scopes = thread_scopes;
  if (scopes.steps.empty() && !receiver) return decisive;
  Runtime& runtime = Runtime::instance();
  const std::uint64_t generation = runtime.generation.load(std::memory_order_acquire);
  const auto key = std::make_pair(&function, receiver);
  if (scopes.generation == generation) {
    if (scopes.last_key == key && scopes.last.generation == generation) return scopes.last.head;
    auto cached = scopes.heads.find(key);
    if (cached != scopes.heads.end() && cached->second.generation == generation) {
      scopes.last_key = key;
      scopes.last = cached->second;
      return cached->second.head;
    }
  }
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  runtime.effective(scopes);  // brings the thread's cache to the current generation
  const void* head = compose(function, runtime.effective_for(scopes, receiver));
  scopes.heads[key] = {scopes.generation, head};
  scopes.last_key = key;
  scopes.last = {scopes.generation, head};
  return head;
}

void throw_no_implementation(const std::string& function, const void* receiver) {
  std::string active;
  Configuration seen;
  {
    Runtime& runtime = Runtime::instance();
    std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
    seen = runtime.effective_for(thread_scopes, receiver);
  }
  for (const auto& name : seen) active += (active.empty() ? "" : ", ") + name;
  throw NoImplementationError(function + " has no base implementation and no active layer " +
                              "refines it (active layers: " + (active.empty() ? "none" : active) +
                              ")");
}

void throw_proceed_past_end(const std::string& function, const char* layer) {
  throw ProceedError("proceed() in " + function +
                     (layer && *layer ? " of layer " + std::string(layer) : std::string(" base")) +
                     " has no next implementation (no base, or called from the base)");
}

}  // namespace detail

using detail::Runtime;

bool operator==(const LayerInfo& a, const LayerInfo& b) {
  return a.name == b.name && a.excludes == b.excludes && a.required == b.required &&
         a.after == b.after && a.group == b.group && a.implies == b.implies;
}

void define_layer(const LayerInfo& layer) { define_layer(layer, "", {}); }

void define_layer(const LayerInfo& layer, std::string description, LayerHooks hooks) {
  if (!detail::is_identifier(layer.name)) {
    throw LayerDefinitionError("layer name '" + layer.name + "' is not an identifier");
  }
  if (!layer.group.empty() && !detail::is_identifier(layer.group)) {
    throw LayerDefinitionError("layer " + layer.name + ": group '" + layer.group +
                               "' is not an identifier");
  }
  for (const auto* relation : {&layer.excludes, &layer.required, &layer.after, &layer.implies}) {
    for (const auto& name : *relation) {
      if (!detail::is_identifier(name)) {
        throw LayerDefinitionError("layer " + layer.name + ": '" + name + "' is not a layer name");
      }
      if (name == layer.name) {
        throw LayerDefinitionError("layer " + layer.name + " cannot name itself in a relation");
      }
    }
  }
  for (const auto& name : layer.required) {
    if (std::find(layer.excludes.begin(), layer.excludes.end(), name) != layer.excludes.end()) {
      throw LayerDefinitionError("layer " + layer.name + " both requires and excludes " + name);
    }
  }
  for (const auto& name : layer.implies) {
    if (std::find(layer.excludes.begin(), layer.excludes.end(), name) != layer.excludes.end()) {
      throw LayerDefinitionError("layer " + layer.name + " both implies and excludes " + name);
    }
  }
  Runtime& runtime = Runtime::instance();
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  runtime.layers[layer.name] = layer;
  runtime.details[layer.name] = {std::move(description), std::move(hooks)};
  ++runtime.generation;  // group membership may change what scopes replay to
}

std::string layer_description(std::string_view layer) {
  Runtime& runtime = Runtime::instance();
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  auto found = runtime.details.find(std::string(layer));
  return found != runtime.details.end() ? found->second.description : std::string();
}

std::vector<LayerInfo> defined_layers() {
  Runtime& runtime = Runtime::instance();
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  std::vector<LayerInfo> result;
  for (const auto& [name, layer] : runtime.layers) result.push_back(layer);
  return result;
}

std::vector<std::string> active_layers() {
  Runtime& runtime = Runtime::instance();
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  return runtime.active;
}

std::vector<std::string> effective_layers() {
  Runtime& runtime = Runtime::instance();
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  if (detail::thread_scopes.steps.empty()) return runtime.active;
  return runtime.effective(detail::thread_scopes);
}

std::uint64_t current_epoch() {
  Runtime& runtime = Runtime::instance();
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  return runtime.epoch;
}

bool in_critical_section() { return Runtime::instance().critical_depth.load() > 0; }

SwitchOutcome set_active(const std::vector<std::string>& layers, SwitchCallback on_settled) {
  Runtime& runtime = Runtime::instance();
  return runtime.request(
      [&runtime, layers](const detail::Configuration&) {
        detail::Configuration wanted = detail::checked_names(layers);
        detail::validate(wanted, runtime.definitions());
        return wanted;
      },
      std::move(on_settled));
}

SwitchOutcome activate(std::string_view layer, SwitchCallback on_settled) {
  Runtime& runtime = Runtime::instance();
  std::string name(layer);
  return runtime.request(
      [&runtime, name](const detail::Configuration& current) {
        return detail::plan(current, detail::checked_names({name}), {}, runtime.definitions());
      },
      std::move(on_settled));
}

SwitchOutcome deactivate(std::string_view layer, SwitchCallback on_settled) {
  Runtime& runtime = Runtime::instance();
  std::string name(layer);
  return runtime.request(
      [&runtime, name](const detail::Configuration& current) {
        return detail::plan(current, {}, detail::checked_names({name}), runtime.definitions());
      },
      std::move(on_settled));
}

std::vector<std::string> activation_order(const std::vector<std::string>& layers) {
  std::vector<std::string> wanted;
  for (const auto& name : layers) {
    if (std::find(wanted.begin(), wanted.end(), name) == wanted.end()) wanted.push_back(name);
  }
  std::map<std::string, std::vector<std::string>> must_follow;
  {
    Runtime& runtime = Runtime::instance();
    std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
    const auto definitions = runtime.definitions();
    for (const auto& name : wanted) {
      for (const auto& earlier : definitions(name).after) {
        if (std::find(wanted.begin(), wanted.end(), earlier) != wanted.end()) {
          must_follow[name].push_back(earlier);
        }
      }
    }
  }
  std::vector<std::string> ordered;
  std::vector<std::string> remaining = wanted;
  while (!remaining.empty()) {
    auto ready = std::find_if(remaining.begin(), remaining.end(), [&](const std::string& name) {
      for (const auto& earlier : must_follow[name]) {
        if (std::find(ordered.begin(), ordered.end(), earlier) == ordered.end()) return false;
      }
      return true;
    });
    if (ready == remaining.end()) {
      std::string names;
      for (const auto& name : remaining) names += (names.empty() ? "" : ", ") + name;
      throw RelationError("the declared 'after' orders of " + names + " form a cycle", remaining);
    }
    ordered.push_back(*ready);
    remaining.erase(ready);
  }
  return ordered;
}

Subscription subscribe(std::function<void(const SwitchEvent&)> observer) {
  Runtime& runtime = Runtime::instance();
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  const std::uint64_t id = runtime.next_observer++;
  runtime.observers.emplace(id, std::move(observer));
  return Subscription(id);
}

Subscription& Subscription::operator=(Subscription&& other) noexcept {
  if (this != &other) {
    reset();
    id_ = std::exchange(other.id_, 0);
  }
  return *this;
}

Subscription::~Subscription() { reset(); }

void Subscription::reset() {
  if (!id_) return;
  Runtime& runtime = Runtime::instance();
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  runtime.observers.erase(std::exchange(id_, 0));
}

CriticalSection::CriticalSection() {
  Runtime& runtime = Runtime::instance();
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  runtime.critical_depth.fetch_add(1);
}

CriticalSection::~CriticalSection() {
  Runtime& runtime = Runtime::instance();
  std::vector<detail::Settled> settled;
  {
    std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
    if (runtime.critical_depth.fetch_sub(1) != 1) return;
    while (!runtime.deferred.empty() && runtime.critical_depth.load() == 0) {
      detail::Pending pending = std::move(runtime.deferred.front());
      runtime.deferred.pop_front();
      SwitchOutcome outcome{SwitchStatus::failed, runtime.epoch, ""};
      try {  // a destructor must not throw
        outcome = runtime.apply(pending.plan);
      } catch (const std::exception& error) {
        outcome.error = error.what();
      } catch (...) {
        outcome.error = "the switch threw";
      }
      settled.push_back({std::move(pending.on_settled), std::move(outcome)});
    }
  }
  for (auto& item : settled) {
    if (!item.on_settled) continue;
    try {
      item.on_settled(item.outcome);
    } catch (...) {  // a destructor must not throw; the switch itself is settled
    }
  }
}

namespace detail {

void activate_for(const void* receiver, const std::vector<std::string>& layers) {
  Runtime& runtime = Runtime::instance();
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  runtime.add_steps(receiver, layers, true);
}

void deactivate_for(const void* receiver, const std::vector<std::string>& layers) {
  Runtime& runtime = Runtime::instance();
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  runtime.add_steps(receiver, layers, false);
}

void reset_for(const void* receiver) {
  Runtime& runtime = Runtime::instance();
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  if (!runtime.receivers.erase(receiver)) return;
  ++runtime.generation;
  runtime.rewire_all();
}

std::vector<std::string> layers_for(const void* receiver) {
  Runtime& runtime = Runtime::instance();
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  return runtime.effective_for(thread_scopes, receiver);
}

}  // namespace detail

ScopedActivation::ScopedActivation(std::string_view layer) : ScopedActivation(layer, true) {}

ScopedActivation::ScopedActivation(std::string_view layer, bool activating) {
  Runtime& runtime = Runtime::instance();
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  auto& scopes = detail::thread_scopes;
  std::vector<detail::Step> steps = scopes.steps;
  steps.push_back({activating, detail::checked_names({std::string(layer)}).front()});
  detail::validate(detail::replay(runtime.active, steps, runtime.definitions()),
                   runtime.definitions());
  scopes.steps = std::move(steps);
  scopes.generation = 0;
  if (++runtime.live_scopes == 1) runtime.rewire_all();
}

ScopedActivation::~ScopedActivation() {
  Runtime& runtime = Runtime::instance();
  std::lock_guard<std::recursive_mutex> lock(runtime.mutex);
  auto& scopes = detail::thread_scopes;
  if (!scopes.steps.empty()) scopes.steps.pop_back();
  scopes.generation = 0;
  if (--runtime.live_scopes == 0) runtime.rewire_all();
}

}  // namespace contextros
