// A small JSON reader for what the tools wrote themselves (markloop-eval
// --summary reads eval.json files back). The whole grammar, numbers as
// double, strings with their escapes (\uXXXX kept only for ASCII).
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "app/common/result.hpp"

namespace markloop::eval {

struct JsonValue {
  enum class Type { Null, Bool, Number, String, Array, Object };
  Type type = Type::Null;
  bool boolean = false;
  double number = 0.0;
  std::string string;
  std::vector<JsonValue> items;                            // Array
  std::vector<std::pair<std::string, JsonValue>> members;  // Object, in file order

  bool is(Type t) const { return type == t; }
  // The member `key` of an object; null when absent or not an object.
  const JsonValue* find(std::string_view key) const;
};

// Nesting deeper than this is refused (no file of the tools nests so deep).
inline constexpr std::size_t kMaxJsonDepth = 64;

// The value the whole text holds; else "byte N: what is wrong".
Result<JsonValue> parse_json(std::string_view text);

}  // namespace markloop::eval
