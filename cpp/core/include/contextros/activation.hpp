// Activation: decisive (process-wide) switches, scoped per-thread activation, critical
// sections and observers. The same semantics as the Python core (docs/core.md).
#pragma once

#include <cstdint>
#include <functional>
#include <initializer_list>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace contextros {

// The decisive configuration: active layers in activation order (last = outermost).
std::vector<std::string> active_layers();
// What the calling thread runs: the decisive configuration with its scoped activations.
std::vector<std::string> effective_layers();
// How many decisive switches have applied in this process.
std::uint64_t current_epoch();
// Whether a critical section is open in any thread (decisive switches are deferred).
bool in_critical_section();

enum class SwitchStatus { applied, deferred, failed };

struct SwitchOutcome {
  SwitchStatus status;
  std::uint64_t epoch;  // the epoch after the switch (applied), else the current one
  std::string error;    // why it failed; with applied, a layer's on_activate hook that threw
                        // (the new configuration stays); else ""
};

using SwitchCallback = std::function<void(const SwitchOutcome&)>;

// Make exactly this ordered list the decisive configuration. Names not defined in this
// process are created bare (transparent). Relations are validated first: a failure changes
// nothing. Inside a critical section the switch is deferred: `on_settled` is called once
// with applied or failed when the last section closes (on the thread that closes it).
// When not deferred, `on_settled` is called before returning as well. An unchanged
// configuration applies without a new epoch.
SwitchOutcome set_active(const std::vector<std::string>& layers, SwitchCallback on_settled = {});
// Activate one layer (newest outermost; an active layer keeps its place; a member of an
// exclusive group replaces the other members) or deactivate one, as set_active does.
SwitchOutcome activate(std::string_view layer, SwitchCallback on_settled = {});
SwitchOutcome deactivate(std::string_view layer, SwitchCallback on_settled = {});

// `layers` ordered so that every declared `after` among them holds (a layer comes after
// those it is declared after, so it runs outermost); unrelated layers keep their order. What
// makes `after` real: `set_active(activation_order({"Night", "Indoor"}))`. Throws
// RelationError naming the layers when their declared orders form a cycle.
std::vector<std::string> activation_order(const std::vector<std::string>& layers);

// An applied decisive switch, as observers see it.
struct SwitchEvent {
  std::uint64_t epoch;
  std::vector<std::string> old_layers;
  std::vector<std::string> new_layers;
};

// Keeps an observer subscribed for its lifetime (RAII). Movable, not copyable.
class Subscription {
 public:
  Subscription() = default;
  Subscription(Subscription&&) noexcept = default;
  Subscription& operator=(Subscription&&) noexcept;
  Subscription(const Subscription&) = delete;
  Subscription& operator=(const Subscription&) = delete;
  ~Subscription();
  void reset();  // unsubscribe now

 private:
  friend Subscription subscribe(std::function<void(const SwitchEvent&)> observer);
  explicit Subscription(std::uint64_t id) : id_(id) {}
  std::uint64_t id_ = 0;
};

// Calls `observer` after every applied decisive switch, in epoch order, on the switching
// thread, while switches are serialised: keep it short. An exception it throws is dropped.
[[nodiscard]] Subscription subscribe(std::function<void(const SwitchEvent&)> observer);

namespace detail {
void activate_for(const void* receiver, const std::vector<std::string>& layers);
void deactivate_for(const void* receiver, const std::vector<std::string>& layers);
void reset_for(const void* receiver);
std::vector<std::string> layers_for(const void* receiver);
}  // namespace detail

// Per-object activation (the Python core's activate_for on an object): `layers` are active
// for the layered methods called on `object` only, outermost, on top of the decisive
// configuration (then the calling thread's scopes come on top). Validated for the object
// first: a relation it would break throws RelationError, nothing changed. A decisive switch
// that conflicts with an object's own layers is never refused: that object's level is
// suspended (the decisive configuration wins) until a switch removes the conflict; while
// it is, changing it throws RelationError (reset_for is allowed). Objects are known by
// address: call reset_for(*this) in the destructor of an object that may have layers of its
// own, or a later object at the same address inherits them. Free functions have no object:
// decisive and scoped layers only.
template <class T, class... Layers>
void activate_for(const T& object, const Layers&... layers) {
  detail::activate_for(std::addressof(object), {std::string(layers)...});
}
// `layers` inactive for the methods called on `object` (hides decisive ones for it).
template <class T, class... Layers>
void deactivate_for(const T& object, const Layers&... layers) {
  detail::deactivate_for(std::addressof(object), {std::string(layers)...});
}
// Forgets `object`'s own layers: its calls follow the decisive configuration again.
template <class T>
void reset_for(const T& object) {
  detail::reset_for(std::addressof(object));
}
// What a method called on `object` from this thread runs: the decisive configuration, the
// object's own layers (unless suspended), then this thread's scopes.
template <class T>
std::vector<std::string> layers_for(const T& object) {
  return detail::layers_for(std::addressof(object));
}

// RAII: while any critical section is open (in any thread), decisive switches are deferred;
// they apply in request order when the last one closes.
class CriticalSection {
 public:
  CriticalSection();
  ~CriticalSection();
  CriticalSection(const CriticalSection&) = delete;
  CriticalSection& operator=(const CriticalSection&) = delete;
};

// RAII, per thread: `layer` is active (outermost) for the calling thread only, on top of
// the decisive configuration, until destruction. Relations are checked on entry
// (RelationError). Destroy in reverse order of construction, on the constructing thread.
class ScopedActivation {
 public:
  explicit ScopedActivation(std::string_view layer);
  ~ScopedActivation();
  ScopedActivation(const ScopedActivation&) = delete;
  ScopedActivation& operator=(const ScopedActivation&) = delete;

 protected:
  ScopedActivation(std::string_view layer, bool activating);
};

// RAII, per thread: `layer` is inactive for the calling thread only.
class ScopedDeactivation : public ScopedActivation {
 public:
  explicit ScopedDeactivation(std::string_view layer) : ScopedActivation(layer, false) {}
};

}  // namespace contextros
