// A small JSON value for the benchmarks' reports (`tandem bench --json`):
// objects keep their keys in insertion order so a report reads like the
// table it mirrors. Writing only; no parser, no dependency.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace tandem {

class JsonValue {
 public:
  JsonValue() = default;  // null
  JsonValue(bool b) : v_(b) {}
  JsonValue(double d) : v_(d) {}
  JsonValue(int i) : v_(int64_t(i)) {}
  JsonValue(int64_t i) : v_(i) {}
  JsonValue(uint32_t u) : v_(int64_t(u)) {}
  JsonValue(uint64_t u) : v_(u) {}
  JsonValue(const char* s) : v_(std::string(s)) {}
  JsonValue(std::string s) : v_(std::move(s)) {}

  static JsonValue object();
  static JsonValue array();

  // On an object: sets `key` (replacing an earlier value of it). Returns
  // *this, so calls chain.
  JsonValue& set(const std::string& key, JsonValue value);
  // On an array: appends.
  JsonValue& push(JsonValue value);

  // Two-space indented text ending in a newline. Non-finite numbers, which
  // JSON cannot represent, are written as null.
  std::string dump() const;

 private:
  struct Object {
    std::vector<std::pair<std::string, JsonValue>> members;
  };
  struct Array {
    std::vector<JsonValue> items;
  };
  void write(std::string& out, int indent) const;
  std::variant<std::monostate, bool, double, int64_t, uint64_t, std::string, Object, Array> v_;
};

// `s` as a JSON string literal, quotes included.
std::string json_quote(const std::string& s);

}  // namespace tandem
