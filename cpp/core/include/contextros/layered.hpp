// Layered functions: the dispatch machinery behind code generated from C++ layer files.
//
// A layered function has a base implementation (or none) and one partial implementation
// per layer that refines it. For every configuration the runtime composes the chain of
// implementations once (the most recently activated layer outermost, then the next older
// one, ..., then the base), caches it for that configuration and installs its head with one
// atomic store. A call is one atomic load and one indirect call of the head; the chain is
// immutable and bound at that moment, so a call and all its proceed() calls run the
// implementations of one configuration, whatever another thread switches meanwhile.
// Composed chains are never freed before the layered function is (a running call may use
// them); there is one per distinct configuration seen.
//
// Generated code (contextros compile) declares one Layered object per function; see
// docs/language.md. Writing one by hand works too:
//
//   static double speed_Indoor(contextros::ProceedOf<double(double)> proceed, double f) {
//     return proceed(f) * 0.5;
//   }
//   static double speed_base(contextros::ProceedOf<double(double)>, double f) { return f; }
//   static contextros::LayeredOf<double(double)> speed_layered{
//       "speed", &speed_base, {{"Indoor", &speed_Indoor}}};
//   double speed(double f) { return speed_layered.invoke(nullptr, f); }
#pragma once

#include <atomic>
#include <cstddef>
#include <initializer_list>
#include <map>
#include <memory>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "contextros/activation.hpp"
#include "contextros/errors.hpp"
#include "contextros/layer.hpp"

namespace contextros {

namespace detail {

// What the runtime knows of a layered function: a name, and how to rewire it.
class LayeredBase {
 public:
  explicit LayeredBase(std::string name) : name_(std::move(name)) {}
  virtual ~LayeredBase();
  LayeredBase(const LayeredBase&) = delete;
  LayeredBase& operator=(const LayeredBase&) = delete;

  const std::string& name() const noexcept { return name_; }

  // Called by the runtime, its lock held: install the chain composed for `configuration`
  // (oldest first), or the scoped entry when `scoped` (threads with scoped activations).
  virtual void rewire(const std::vector<std::string>& configuration, bool scoped) = 0;

 protected:
  // Registers with the runtime, which rewires the function at once. The last thing a
  // derived constructor does (the runtime may call rewire() from then on).
  void enroll();
  // Unregisters (waiting for a switch in progress). The first thing a derived destructor
  // does: no switch may rewire() a half-destroyed function.
  void unenroll() noexcept;

 private:
  std::string name_;
  bool enrolled_ = false;
};

// The scoped call path (taken while scoped activations exist somewhere in the process):
// the head of `function`'s chain for the calling thread. A thread without scopes gets
// `decisive`; one with scopes, the chain composed for its configuration, cached per thread
// until its scopes or the decisive configuration change (composing takes the runtime lock).
using Compose = const void* (*)(const LayeredBase& function,
                                const std::vector<std::string>& configuration);
const void* scoped_head(const LayeredBase& function, const void* decisive, Compose compose);

[[noreturn]] void throw_no_implementation(const std::string& function);
[[noreturn]] void throw_proceed_past_end(const std::string& function, const char* layer);

}  // namespace detail

template <class Self, class Signature>
class Layered;

// A layered function of signature R(Args...); Self is the class (const-qualified for a const
// method) for a layered method, void for a free function.
template <class Self, class R, class... Args>
class Layered<Self, R(Args...)> final : public detail::LayeredBase {
 public:
  class Proceed;
  // An implementation: a partial or the base. `proceed` runs the next one.
  using Impl = R (*)(Proceed proceed, Args... args);

  struct Partial {
    std::string layer;
    Impl impl;
  };

  // One link of a composed chain.
  struct Node {
    Impl fn;
    const Node* next;
    const Layered* owner;
    const char* layer;  // the layer whose partial this is; "" for the base
  };

  // The next implementation of the running chain, and the object of a method.
  class Proceed {
   public:
    R operator()(Args... args) const {
      const Node* next = node_->next;
      return next->fn(Proceed(next, self_), std::forward<Args>(args)...);
    }
    // The object a layered method runs on.
    std::add_lvalue_reference_t<Self> self() const noexcept { return *self_; }

   private:
    friend class Layered;
    Proceed(const Node* node, Self* self) noexcept : node_(node), self_(self) {}
    const Node* node_;
    Self* self_;
  };

  // `base` may be null (no base: a call with no active partial throws
  // NoImplementationError). One partial per layer.
  Layered(std::string name, Impl base, std::initializer_list<Partial> partials)
      : detail::LayeredBase(std::move(name)), base_(base), partials_(partials) {
    scoped_entry_ = Node{&Layered::scoped_entry, nullptr, this, ""};
    enroll();
  }
  ~Layered() override { unenroll(); }
  Layered(const Layered&) = delete;
  Layered& operator=(const Layered&) = delete;

  // The call: one atomic load and one indirect call.
  R invoke(Self* self, Args... args) const {
    const Node* head = head_.load(std::memory_order_acquire);
    return head->fn(Proceed(head, self), std::forward<Args>(args)...);
  }

  void rewire(const std::vector<std::string>& configuration, bool scoped) override {
    const Node* chain = compose(configuration);
    decisive_.store(chain, std::memory_order_release);
    head_.store(scoped ? &scoped_entry_ : chain, std::memory_order_release);
  }

 private:
  // The chain for `configuration` (oldest first), composed once and cached. Runtime lock held.
  const Node* compose(const std::vector<std::string>& configuration) const {
    std::vector<std::size_t> refining;
    for (auto layer = configuration.rbegin(); layer != configuration.rend(); ++layer) {
      for (std::size_t i = 0; i < partials_.size(); ++i) {
        if (partials_[i].layer == *layer) refining.push_back(i);
      }
    }
    auto found = chains_.find(refining);
    if (found != chains_.end()) return found->second.get();
    const std::size_t size = refining.size() + (base_ ? 1 : 0) + 1;
    auto nodes = std::make_unique<Node[]>(size);
    std::size_t at = 0;
    for (std::size_t index : refining) {
      nodes[at] = Node{partials_[index].impl, &nodes[at + 1], this, partials_[index].layer.c_str()};
      ++at;
    }
    if (base_) {
      nodes[at] = Node{base_, &nodes[at + 1], this, ""};
      ++at;
    }
    const char* last = at ? nodes[at - 1].layer : "";
    nodes[at] = Node{at ? &Layered::past_end : &Layered::no_implementation, nullptr, this, last};
    const Node* head = nodes.get();
    chains_.emplace(std::move(refining), std::move(nodes));
    return head;
  }

  // Installed while scoped activations exist: finds the calling thread's chain.
  static R scoped_entry(Proceed proceed, Args... args) {
    const Layered* self = proceed.node_->owner;
    const Node* head = static_cast<const Node*>(detail::scoped_head(
        *self, self->decisive_.load(std::memory_order_acquire), &Layered::compose_for));
    return head->fn(Proceed(head, proceed.self_), std::forward<Args>(args)...);
  }

  static const void* compose_for(const detail::LayeredBase& function,
                                 const std::vector<std::string>& configuration) {
    return static_cast<const Layered&>(function).compose(configuration);
  }

  static R no_implementation(Proceed proceed, Args...) {
    detail::throw_no_implementation(proceed.node_->owner->name());
  }

  static R past_end(Proceed proceed, Args...) {
    detail::throw_proceed_past_end(proceed.node_->owner->name(), proceed.node_->layer);
  }

  Impl base_;
  std::vector<Partial> partials_;
  Node scoped_entry_{};
  std::atomic<const Node*> head_{nullptr};
  std::atomic<const Node*> decisive_{nullptr};
  // Every chain ever composed, by the refining partials (newest first). Never shrinks.
  mutable std::map<std::vector<std::size_t>, std::unique_ptr<Node[]>> chains_;
};

// Traits from a function type or a pointer to member function.
template <class F>
struct LayeredTraits;

template <class R, class... Args>
struct LayeredTraits<R(Args...)> {
  using type = Layered<void, R(Args...)>;
  using result = R;
};
template <class R, class... Args>
struct LayeredTraits<R(Args...) noexcept> : LayeredTraits<R(Args...)> {};

#define CONTEXTROS_DETAIL_MEMBER_TRAITS(QUALIFIERS, SELF)                     \
  template <class R, class C, class... Args>                                  \
  struct LayeredTraits<R (C::*)(Args...) QUALIFIERS> {                        \
    using type = Layered<SELF, R(Args...)>;                                   \
    using result = R;                                                         \
  };                                                                          \
  template <class R, class C, class... Args>                                  \
  struct LayeredTraits<R (C::*)(Args...) QUALIFIERS noexcept>                 \
      : LayeredTraits<R (C::*)(Args...) QUALIFIERS> {};
CONTEXTROS_DETAIL_MEMBER_TRAITS(, C)
CONTEXTROS_DETAIL_MEMBER_TRAITS(const, const C)
#undef CONTEXTROS_DETAIL_MEMBER_TRAITS

// The Layered type for a function type (`decltype(getPos)`) or a member function pointer
// type (`decltype(&Robot::getPos)`), and the type of its `proceed`.
template <class F>
using LayeredOf = typename LayeredTraits<F>::type;
template <class F>
using ProceedOf = typename LayeredOf<F>::Proceed;
template <class F>
using ResultOf = typename LayeredTraits<F>::result;

// Calls the per-layer member implementations of a class (see CONTEXTROS_LAYERED_CLASS):
// `&MethodThunk<Tag, decltype(&Robot::getPos)>::call` is the implementation of a layer.
template <class Tag, class F>
struct MethodThunk;

template <class Tag, class R, class C, class... Args>
struct MethodThunk<Tag, R (C::*)(Args...)> {
  using Proceed = typename Layered<C, R(Args...)>::Proceed;
  static R call(Proceed proceed, Args... args) {
    return proceed.self().template contextros_impl<Tag, Proceed, Args...>(
        proceed, std::forward<Args>(args)...);
  }
};
template <class Tag, class R, class C, class... Args>
struct MethodThunk<Tag, R (C::*)(Args...) const> {
  using Proceed = typename Layered<const C, R(Args...)>::Proceed;
  static R call(Proceed proceed, Args... args) {
    return proceed.self().template contextros_impl<Tag, Proceed, Args...>(
        proceed, std::forward<Args>(args)...);
  }
};
template <class Tag, class R, class C, class... Args>
struct MethodThunk<Tag, R (C::*)(Args...) noexcept> : MethodThunk<Tag, R (C::*)(Args...)> {};
template <class Tag, class R, class C, class... Args>
struct MethodThunk<Tag, R (C::*)(Args...) const noexcept>
    : MethodThunk<Tag, R (C::*)(Args...) const> {};

}  // namespace contextros

// Placed in the body of a class whose methods a layer file refines: declares the member
// templates that hold the per-layer implementations (explicit specialisations, one per layer
// and method, generated from the layer file) and lets the generated code reach them. It does
// not change the access of the members around it. The compiler adds it by itself to a class
// defined in the layer file's header part.
#define CONTEXTROS_LAYERED_CLASS                                            \
  template <class ContextrosTag, class... ContextrosArgs>                   \
  typename ContextrosTag::result contextros_impl(ContextrosArgs... args);   \
  template <class ContextrosTag, class... ContextrosArgs>                   \
  typename ContextrosTag::result contextros_impl(ContextrosArgs... args) const; \
  template <class, class>                                                   \
  friend struct ::contextros::MethodThunk
