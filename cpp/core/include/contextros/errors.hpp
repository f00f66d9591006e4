// The exceptions of the C++ COP runtime: the same hierarchy as the Python core's
// (src/contextros/errors.py), rooted at LayerError.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

namespace contextros {

// Root of every error the runtime throws.
class LayerError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A requested configuration breaks a declared relation (excludes, required, group).
// Nothing changed when this is thrown: switches are validated before they apply.
class RelationError : public LayerError {
 public:
  RelationError(const std::string& message, std::vector<std::string> layers)
      : LayerError(message), layers_(std::move(layers)) {}
  // The layers involved, as named in the message.
  const std::vector<std::string>& layers() const noexcept { return layers_; }

 private:
  std::vector<std::string> layers_;
};

// A layer was declared inconsistently (a relation naming itself, requires and excludes of
// the same layer, a name that is not an identifier).
class LayerDefinitionError : public LayerError {
 public:
  using LayerError::LayerError;
};

// A layer's on_activate or on_deactivate hook threw: the message names the layer and the
// hook and holds the hook's own message. A decisive switch reports it in its outcome.
class HookError : public LayerError {
 public:
  HookError(const std::string& message, std::string layer)
      : LayerError(message), layer_(std::move(layer)) {}
  const std::string& layer() const noexcept { return layer_; }

 private:
  std::string layer_;
};

// A layered call could not find an implementation to run.
class DispatchError : public LayerError {
 public:
  using LayerError::LayerError;
};

// A layered function has no base implementation and no active layer refines it.
class NoImplementationError : public DispatchError {
 public:
  using DispatchError::DispatchError;
};

// proceed() was called where there is no next implementation.
class ProceedError : public DispatchError {
 public:
  using DispatchError::DispatchError;
};

}  // namespace contextros
