#include "app/json_writer.h"

#include <charconv>
#include <cmath>
#include <stdexcept>

namespace tandem {

JsonValue JsonValue::object() {
  JsonValue v;
  v.v_ = Object{};
  return v;
}

JsonValue JsonValue::array() {
  JsonValue v;
  v.v_ = Array{};
  return v;
}

JsonValue& JsonValue::set(const std::string& key, JsonValue value) {
  Object* o = std::get_if<Object>(&v_);
  if (!o) throw std::logic_error("JsonValue::set on a value that is not an object");
  for (auto& [k, v] : o->members) {
    if (k == key) {
      v = std::move(value);
      return *this;
    }
  }
  o->members.emplace_back(key, std::move(value));
  return *this;
}

JsonValue& JsonValue::push(JsonValue value) {
  Array* a = std::get_if<Array>(&v_);
  if (!a) throw std::logic_error("JsonValue::push on a value that is not an array");
  a->items.push_back(std::move(value));
  return *this;
}

std::string json_quote(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (u < 0x20) {
          static const char* hex = "0123456789abcdef";
          out += "\\u00";
          out += hex[u >> 4];
          out += hex[u & 15];
        } else {
          out += c;  // UTF-8 passes through unchanged
        }
    }
  }
  return out + "\"";
}

namespace {

void newline(std::string& out, int indent) {
  out += '\n';
  out.append(size_t(indent) * 2, ' ');
}

// Shortest text that reads back as the same double.
std::string format_double(double d) {
  if (!std::isfinite(d)) return "null";
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof(buf), d);
  return std::string(buf, r.ptr);
}

}  // namespace

void JsonValue::write(std::string& out, int indent) const {
  if (std::holds_alternative<std::monostate>(v_)) {
    out += "null";
  } else if (const bool* b = std::get_if<bool>(&v_)) {
    out += *b ? "true" : "false";
  } else if (const double* d = std::get_if<double>(&v_)) {
    out += format_double(*d);
  } else if (const int64_t* i = std::get_if<int64_t>(&v_)) {
    out += std::to_string(*i);
  } else if (const uint64_t* u = std::get_if<uint64_t>(&v_)) {
    out += std::to_string(*u);
  } else if (const std::string* s = std::get_if<std::string>(&v_)) {
    out += json_quote(*s);
  } else if (const Object* o = std::get_if<Object>(&v_)) {
    if (o->members.empty()) {
      out += "{}";
      return;
    }
    out += '{';
    for (size_t m = 0; m < o->members.size(); ++m) {
      newline(out, indent + 1);
      out += json_quote(o->members[m].first);
      out += ": ";
      o->members[m].second.write(out, indent + 1);
      if (m + 1 < o->members.size()) out += ',';
    }
    newline(out, indent);
    out += '}';
  } else if (const Array* a = std::get_if<Array>(&v_)) {
    if (a->items.empty()) {
      out += "[]";
      return;
    }
    out += '[';
    for (size_t m = 0; m < a->items.size(); ++m) {
      newline(out, indent + 1);
      a->items[m].write(out, indent + 1);
      if (m + 1 < a->items.size()) out += ',';
    }
    newline(out, indent);
    out += ']';
  }
}

std::string JsonValue::dump() const {
  std::string out;
  write(out, 0);
  return out + '\n';
}

}  // namespace tandem
