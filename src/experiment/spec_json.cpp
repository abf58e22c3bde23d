// experiment: a JSON spec as a SpecTree. nlohmann-json reports no positions of values, so each key's line is
// located in the text: the keys are visited in document order (ordered_json) and each is searched as
// "KEY": from the previous key's position on. A syntax error's line comes from the parser's byte offset.
#include "experiment/spec_tree.h"

#include <algorithm>
#include <string>
#include <vector>

namespace microsim::experiment {
namespace {

int line_at(std::string_view text, std::size_t offset) {
  offset = std::min(offset, text.size());
  return 1 + int(std::count(text.begin(), text.begin() + std::ptrdiff_t(offset), '\n'));
}

// Walks `value` in document order, recording the line of every key (and of every array item: its parent
// key's line, a JSON array item has no name to search for).
class KeyLocator {
public:
  KeyLocator(std::string_view text, SpecTree& tree) : text_(text), tree_(tree) {}

  void visit(const nlohmann::ordered_json& value, const std::string& path, int line) {
    if (value.is_object()) {
      for (const auto& [key, child] : value.items()) {
        const std::string child_path_text = child_path(path, key);
        const int child_line = locate(key);
        tree_.lines[child_path_text] = child_line;
        visit(child, child_path_text, child_line);
      }
    } else if (value.is_array()) {
      for (std::size_t i = 0; i < value.size(); ++i) {
        tree_.lines[item_path(path, i)] = line;
        visit(value[i], item_path(path, i), line);
      }
    }
  }

private:
  int locate(const std::string& key) {
    const std::string quoted = nlohmann::json(key).dump() + ":";  // "key": (the usual spelling)
    std::size_t at = text_.find(quoted, cursor_);
    if (at == std::string_view::npos) at = text_.find(nlohmann::json(key).dump(), cursor_);  // "key" :
    if (at == std::string_view::npos) return 0;
    cursor_ = at + 1;
    return line_at(text_, at);
  }

  std::string_view text_;
  SpecTree& tree_;
  std::size_t cursor_ = 0;
};

// The parser's callback that refuses a key given twice in one object (nlohmann-json keeps the last silently; TOML
// refuses it): SpecError naming the key.
nlohmann::ordered_json::parser_callback_t refuse_repeated_keys(const std::string& source) {
  using Event = nlohmann::ordered_json::parse_event_t;
  return [&source, open = std::vector<std::vector<std::string>>()](int, Event event,
                                                                    nlohmann::ordered_json& parsed) mutable {
    if (event == Event::object_start) open.emplace_back();
    if (event == Event::object_end && !open.empty()) open.pop_back();
    if (event == Event::key && !open.empty()) {
      const std::string key = parsed.get<std::string>();
      if (std::find(open.back().begin(), open.back().end(), key) != open.back().end())
        throw SpecError(source, 0, key, "given twice in one table (only one value can hold)");
      open.back().push_back(key);
    }
    return true;
  };
}

}  // namespace

SpecTree json_tree(std::string_view text, const std::string& source) {
  SpecTree tree;
  tree.source = source;
  try {
    tree.root = nlohmann::ordered_json::parse(text.begin(), text.end(), refuse_repeated_keys(source));
  } catch (const nlohmann::json::parse_error& e) {
    throw SpecError(source, line_at(text, e.byte > 0 ? e.byte - 1 : 0), "(syntax)", e.what());
  }
  if (!tree.root.is_object()) throw SpecError(source, 1, "(document)", "a spec is a JSON object");
  KeyLocator(text, tree).visit(tree.root, "", 1);
  return tree;
}

}  // namespace microsim::experiment
