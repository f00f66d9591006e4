#include "configuration.hpp"

#include <algorithm>
#include <map>
#include <set>

#include "contextros/errors.hpp"

namespace contextros::detail {
namespace {

bool contains(const std::vector<std::string>& names, const std::string& name) {
  return std::find(names.begin(), names.end(), name) != names.end();
}

Configuration with(Configuration layers, const std::string& layer, const Definitions& definitions) {
  const std::string group = definitions(layer).group;
  if (!group.empty()) {
    layers.erase(std::remove_if(layers.begin(), layers.end(),
                                [&](const std::string& other) {
                                  return other != layer && definitions(other).group == group;
                                }),
                 layers.end());
  }
  if (!contains(layers, layer)) layers.push_back(layer);
  return layers;
}

}  // namespace

bool is_identifier(const std::string& name) { return is_layer_name(name); }

void validate(const Configuration& configuration, const Definitions& definitions) {
  std::set<std::string> active;
  std::set<std::string> repeated;
  for (const auto& name : configuration) {
    if (!active.insert(name).second) repeated.insert(name);
  }
  if (!repeated.empty()) {
    std::string names;
    for (const auto& name : repeated) names += (names.empty() ? "" : ", ") + name;
    throw RelationError("layer(s) " + names + " listed twice",
                        std::vector<std::string>(repeated.begin(), repeated.end()));
  }
  std::map<std::string, std::string> groups;
  for (const auto& name : configuration) {
    const LayerInfo definition = definitions(name);
    std::set<std::string> excludes(definition.excludes.begin(), definition.excludes.end());
    for (const auto& other : excludes) {
      if (active.count(other)) {
        throw RelationError("layers " + name + " and " + other + " cannot be active together (" +
                                name + " excludes " + other + ")",
                            {name, other});
      }
    }
    std::set<std::string> required(definition.required.begin(), definition.required.end());
    for (const auto& needed : required) {
      if (!active.count(needed)) {
        throw RelationError("layer " + name + " requires " + needed +
                                ", which would not be active (activate " + needed +
                                " too, or deactivate " + name + ")",
                            {name, needed});
      }
    }
    if (!definition.group.empty()) {
      auto [it, inserted] = groups.emplace(definition.group, name);
      if (!inserted) {
        throw RelationError("layers " + it->second + " and " + name +
                                " are both in exclusive group '" + definition.group + "'",
                            {it->second, name});
      }
    }
  }
}

Configuration plan(const Configuration& current, const std::vector<std::string>& activate,
                   const std::vector<std::string>& deactivate, const Definitions& definitions) {
  std::set<std::string> both;
  for (const auto& name : activate) {
    if (contains(deactivate, name)) both.insert(name);
  }
  if (!both.empty()) {
    std::string names;
    for (const auto& name : both) names += (names.empty() ? "" : ", ") + name;
    throw RelationError(
        "layer(s) " + names + " asked to be both activated and deactivated in one switch",
        std::vector<std::string>(both.begin(), both.end()));
  }
  std::map<std::string, std::string> requested;
  for (const auto& name : activate) {
    const std::string group = definitions(name).group;
    if (group.empty()) continue;
    auto [it, inserted] = requested.emplace(group, name);
    if (!inserted && it->second != name) {
      throw RelationError("layers " + it->second + " and " + name +
                              " are both in exclusive group '" + group +
                              "'; activate only one of them",
                          {it->second, name});
    }
  }
  Configuration layers;
  for (const auto& name : current) {
    if (!contains(deactivate, name)) layers.push_back(name);
  }
  for (const auto& name : activate) layers = with(std::move(layers), name, definitions);
  validate(layers, definitions);
  return layers;
}

Configuration replay(const Configuration& current, const std::vector<Step>& steps,
                     const Definitions& definitions) {
  Configuration layers = current;
  for (const auto& step : steps) {
    if (step.activating) {
      layers = with(std::move(layers), step.layer, definitions);
    } else {
      layers.erase(std::remove(layers.begin(), layers.end(), step.layer), layers.end());
    }
  }
  return layers;
}

}  // namespace contextros::detail

namespace contextros {

namespace {

// The code point starting at `at` (advanced past it), or -1 for ill-formed UTF-8.
long next_code_point(std::string_view text, std::size_t& at) {
  const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(text[i]); };
  const unsigned char lead = byte(at);
  std::size_t length = 0;
  long point = 0;
  long minimum = 0;
  if (lead < 0x80) {
    ++at;
    return lead;
  } else if (lead >= 0xc2 && lead <= 0xdf) {
    length = 2, point = lead & 0x1f, minimum = 0x80;
  } else if (lead >= 0xe0 && lead <= 0xef) {
    length = 3, point = lead & 0x0f, minimum = 0x800;
  } else if (lead >= 0xf0 && lead <= 0xf4) {
    length = 4, point = lead & 0x07, minimum = 0x10000;
  } else {
    return -1;
  }
  if (at + length > text.size()) return -1;
  for (std::size_t i = 1; i < length; ++i) {
    if ((byte(at + i) & 0xc0) != 0x80) return -1;
    point = (point << 6) | (byte(at + i) & 0x3f);
  }
  if (point < minimum || point > 0x10ffff || (point >= 0xd800 && point <= 0xdfff)) return -1;
  at += length;
  return point;
}

bool ascii_letter(long c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_'; }

// Beyond ASCII: not a C1 control, nor a Latin-1 sign or punctuation (but ª µ º), nor × ÷.
bool other_letter(long c) {
  if (c < 0xa0) return false;
  if (c <= 0xbf) return c == 0xaa || c == 0xb5 || c == 0xba;
  return c != 0xd7 && c != 0xf7;
}

}  // namespace

bool is_layer_name(std::string_view name) {
  std::size_t at = 0;
  bool first = true;
  while (at < name.size()) {
    const long c = next_code_point(name, at);
    if (c < 0) return false;
    const bool letter = ascii_letter(c) || (c >= 0x80 && other_letter(c));
    if (!letter && (first || !(c >= '0' && c <= '9'))) return false;
    first = false;
  }
  return !first;
}

}  // namespace contextros
