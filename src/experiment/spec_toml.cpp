// experiment: a TOML spec (toml++) as a SpecTree: values converted to JSON, each key's line from the node's
// source region.
#include "experiment/spec_tree.h"

#include <toml++/toml.h>

#include <fmt/core.h>

namespace microsim::experiment {
namespace {

nlohmann::ordered_json to_json(const toml::node& node, const std::string& path, SpecTree& tree);

nlohmann::ordered_json table_json(const toml::table& table, const std::string& path, SpecTree& tree) {
  nlohmann::ordered_json out = nlohmann::ordered_json::object();
  for (const auto& [key, value] : table) {
    const std::string child = child_path(path, key.str());
    const int line = int(key.source().begin.line ? key.source().begin.line : value.source().begin.line);
    if (line > 0) tree.lines[child] = line;
    out[std::string(key.str())] = to_json(value, child, tree);
  }
  return out;
}

nlohmann::ordered_json array_json(const toml::array& array, const std::string& path, SpecTree& tree) {
  nlohmann::ordered_json out = nlohmann::ordered_json::array();
  for (std::size_t i = 0; i < array.size(); ++i) {
    const std::string child = item_path(path, i);
    if (array[i].source().begin.line > 0) tree.lines[child] = int(array[i].source().begin.line);
    out.push_back(to_json(array[i], child, tree));
  }
  return out;
}

nlohmann::ordered_json to_json(const toml::node& node, const std::string& path, SpecTree& tree) {
  if (const auto* t = node.as_table()) return table_json(*t, path, tree);
  if (const auto* a = node.as_array()) return array_json(*a, path, tree);
  if (const auto* s = node.as_string()) return s->get();
  if (const auto* i = node.as_integer()) return i->get();
  if (const auto* f = node.as_floating_point()) return f->get();
  if (const auto* b = node.as_boolean()) return b->get();
  // Dates and times: no spec key takes one; kept as a marker so that the reader names the key.
  return "(a date or time)";
}

}  // namespace

SpecTree toml_tree(std::string_view text, const std::string& source) {
  SpecTree tree;
  tree.source = source;
  try {
    const toml::table table = toml::parse(text, source);
    tree.root = table_json(table, "", tree);
  } catch (const toml::parse_error& e) {
    throw SpecError(source, int(e.source().begin.line), "(syntax)", std::string(e.description()));
  }
  return tree;
}

}  // namespace microsim::experiment
