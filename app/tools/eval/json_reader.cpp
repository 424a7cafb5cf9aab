#include "app/tools/eval/json_reader.hpp"

#include <cmath>
#include <cstdlib>

namespace markloop::eval {

namespace {

class Parser {
 public:
  explicit Parser(std::string_view text) : text_(text) {}

  Result<JsonValue> document() {
    JsonValue v;
    if (!value(v, 0)) return failure();
    skip_space();
    if (at_ < text_.size()) fail_with("text after the value");
    if (!problem_.empty()) return failure();
    return v;
  }

 private:
  Error failure() const { return error("byte " + std::to_string(problem_at_ + 1) + ": " + problem_); }

  bool fail_with(const std::string& what) {
    if (problem_.empty()) problem_ = what, problem_at_ = at_;
    return false;
  }

  void skip_space() {
    while (at_ < text_.size() &&
           (text_[at_] == ' ' || text_[at_] == '\n' || text_[at_] == '\r' || text_[at_] == '\t'))
      ++at_;
  }

  bool take(char c) {
    skip_space();
    if (at_ < text_.size() && text_[at_] == c) return ++at_, true;
    return false;
  }

  bool word(std::string_view w) {
    if (text_.substr(at_, w.size()) != w) return fail_with("unknown word");
    at_ += w.size();
    return true;
  }

  bool value(JsonValue& v, std::size_t depth) {
    if (depth > kMaxJsonDepth) return fail_with("nested too deep");
    skip_space();
    if (at_ >= text_.size()) return fail_with("a value is missing");
    switch (text_[at_]) {
      case '{':
        return object(v, depth);
      case '[':
        return array(v, depth);
      case '"':
        v.type = JsonValue::Type::String;
        return string(v.string);
      case 't':
        v.type = JsonValue::Type::Bool, v.boolean = true;
        return word("true");
      case 'f':
        v.type = JsonValue::Type::Bool;
        return word("false");
      case 'n':
        return word("null");
      default:
        return number(v);
    }
  }

  bool number(JsonValue& v) {
    const std::string token(text_.substr(at_, text_.find_first_of(",]} \n\r\t", at_) - at_));
    char* end = nullptr;
    v.number = std::strtod(token.c_str(), &end);
    if (token.empty() || end != token.c_str() + token.size() || !std::isfinite(v.number))
      return fail_with("not a number");
    v.type = JsonValue::Type::Number;
    at_ += token.size();
    return true;
  }

  bool string(std::string& out) {
    ++at_;  // the opening quote
    while (at_ < text_.size() && text_[at_] != '"') {
      char c = text_[at_++];
      if (c == '\\') {
        if (at_ >= text_.size()) break;
        if (!escape(text_[at_++], out)) return false;
        continue;
      }
      out += c;
    }
    if (at_ >= text_.size()) return fail_with("a string is not closed");
    ++at_;
    return true;
  }

  bool escape(char c, std::string& out) {
    static constexpr std::string_view kFrom = "\"\\/bfnrt", kTo = "\"\\/\b\f\n\r\t";
    if (const std::size_t i = kFrom.find(c); i != std::string_view::npos) return out += kTo[i], true;
    if (c != 'u' || at_ + 4 > text_.size()) return fail_with("bad escape in a string");
    const unsigned code =
        static_cast<unsigned>(std::strtoul(std::string(text_.substr(at_, 4)).c_str(), nullptr, 16));
    at_ += 4;
    out += code < 0x80 ? static_cast<char>(code) : '?';
    return true;
  }

  bool array(JsonValue& v, std::size_t depth) {
    ++at_;
    v.type = JsonValue::Type::Array;
    if (take(']')) return true;
    do {
      v.items.emplace_back();
      if (!value(v.items.back(), depth + 1)) return false;
    } while (take(','));
    return take(']') || fail_with("',' or ']' expected");
  }

  bool object(JsonValue& v, std::size_t depth) {
    ++at_;
    v.type = JsonValue::Type::Object;
    if (take('}')) return true;
    do {
      skip_space();
      if (at_ >= text_.size() || text_[at_] != '"') return fail_with("a member name expected");
      std::string key;
      if (!string(key)) return false;
      if (!take(':')) return fail_with("':' expected");
      v.members.emplace_back(std::move(key), JsonValue{});
      if (!value(v.members.back().second, depth + 1)) return false;
    } while (take(','));
    return take('}') || fail_with("',' or '}' expected");
  }

  std::string_view text_;
  std::size_t at_ = 0;
  std::string problem_;
  std::size_t problem_at_ = 0;
};

}  // namespace

const JsonValue* JsonValue::find(std::string_view key) const {
  for (const auto& [name, value] : members)
    if (name == key) return &value;
  return nullptr;
}

Result<JsonValue> parse_json(std::string_view text) {
  return Parser(text).document();
}

}  // namespace markloop::eval
