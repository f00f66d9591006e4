#include "contextros/ros/rcl_node.hpp"

#include <rcl/rcl.h>

#include "contextros/ros/rcl_handles.hpp"

namespace contextros::ros {

struct RclContext::Impl {
  rcl_context_t context = rcl_get_zero_initialized_context();
};

RclContext::RclContext(int argc, const char* const* argv) : impl_(std::make_unique<Impl>()) {
  rcl_init_options_t options = rcl_get_zero_initialized_init_options();
  detail::check(rcl_init_options_init(&options, rcl_get_default_allocator()),
                "cannot initialise rcl's options");
  const rcl_ret_t ret = rcl_init(argc, argv, &options, &impl_->context);
  detail::ignore_failure(rcl_init_options_fini(&options));
  detail::check(ret, "cannot initialise rcl");
}

RclContext::~RclContext() {
  if (rcl_context_is_valid(&impl_->context)) {
    detail::ignore_failure(rcl_shutdown(&impl_->context));
  }
  detail::ignore_failure(rcl_context_fini(&impl_->context));
}

rcl_context_t& RclContext::get() { return impl_->context; }

bool RclContext::ok() { return rcl_context_is_valid(&impl_->context); }

struct RclNode::Impl {
  rcl_node_t node = rcl_get_zero_initialized_node();
};

RclNode::RclNode(RclContext& context, const std::string& name, const std::string& name_space)
    : impl_(std::make_unique<Impl>()) {
  rcl_node_options_t options = rcl_node_get_default_options();
  const rcl_ret_t ret =
      rcl_node_init(&impl_->node, name.c_str(), name_space.c_str(), &context.get(), &options);
  detail::ignore_failure(rcl_node_options_fini(&options));
  detail::check(ret, ("cannot create the node '" + name + "'").c_str());
}

RclNode::~RclNode() {
  detail::ignore_failure(rcl_node_fini(&impl_->node));
}

rcl_node_t& RclNode::get() { return impl_->node; }

std::string RclNode::fully_qualified_name() const {
  const char* name = rcl_node_get_fully_qualified_name(&impl_->node);
  return name != nullptr ? name : "";
}

}  // namespace contextros::ros
