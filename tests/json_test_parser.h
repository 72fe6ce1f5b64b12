// A strict little JSON parser for tests that read back what Tandem writes
// (benchmark reports). Written apart from app/json_writer so that a bug in
// the writer cannot hide behind the same bug in the reader. Throws
// std::runtime_error with the offset on anything that is not JSON.
#pragma once

#include <cstdlib>
#include <stdexcept>
#include <string>
#include <vector>

namespace tandem::json_test {

struct Member;

struct Node {
  enum class Type { kNull, kBool, kNumber, kString, kArray, kObject } type = Type::kNull;
  bool boolean = false;
  double number = 0.0;
  std::string string;
  std::vector<Node> items;      // arrays
  std::vector<Member> members;  // objects, in order

  bool has(const std::string& key) const;
  const Node& operator[](const std::string& key) const;
  const Node& operator[](size_t i) const { return items.at(i); }
  bool is_number() const { return type == Type::kNumber; }
  bool is_string() const { return type == Type::kString; }
};

// Not std::pair: a pair needs Node complete where Node declares its members
// (libstdc++ accepts that under g++, clang rejects it).
struct Member {
  std::string first;
  Node second;
};

inline bool Node::has(const std::string& key) const {
  for (const auto& m : members)
    if (m.first == key) return true;
  return false;
}

inline const Node& Node::operator[](const std::string& key) const {
  for (const auto& m : members)
    if (m.first == key) return m.second;
  throw std::runtime_error("no key '" + key + "'");
}

class Parser {
 public:
  explicit Parser(const std::string& text) : s_(text) {}
  Node parse_document() {
    Node n = value();
    space();
    if (i_ != s_.size()) fail("text after the value");
    return n;
  }

 private:
  [[noreturn]] void fail(const std::string& why) const {
    throw std::runtime_error("invalid JSON at offset " + std::to_string(i_) + ": " + why);
  }
  void space() {
    while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\n' || s_[i_] == '\r' || s_[i_] == '\t'))
      ++i_;
  }
  bool literal(const char* word) {
    const std::string w(word);
    if (s_.compare(i_, w.size(), w) != 0) return false;
    i_ += w.size();
    return true;
  }
  Node value() {
    space();
    if (i_ >= s_.size()) fail("unexpected end");
    Node n;
    const char c = s_[i_];
    if (c == '{') {
      n.type = Node::Type::kObject;
      ++i_;
      space();
      if (i_ < s_.size() && s_[i_] == '}') {
        ++i_;
        return n;
      }
      for (;;) {
        space();
        if (i_ >= s_.size() || s_[i_] != '"') fail("expected a key");
        std::string key = string_literal();
        for (const auto& m : n.members)
          if (m.first == key) fail("duplicate key '" + key + "'");
        space();
        if (i_ >= s_.size() || s_[i_] != ':') fail("expected ':'");
        ++i_;
        n.members.push_back(Member{key, value()});
        space();
        if (i_ < s_.size() && s_[i_] == ',') {
          ++i_;
          continue;
        }
        if (i_ < s_.size() && s_[i_] == '}') {
          ++i_;
          return n;
        }
        fail("expected ',' or '}'");
      }
    }
    if (c == '[') {
      n.type = Node::Type::kArray;
      ++i_;
      space();
      if (i_ < s_.size() && s_[i_] == ']') {
        ++i_;
        return n;
      }
      for (;;) {
        n.items.push_back(value());
        space();
        if (i_ < s_.size() && s_[i_] == ',') {
          ++i_;
          continue;
        }
        if (i_ < s_.size() && s_[i_] == ']') {
          ++i_;
          return n;
        }
        fail("expected ',' or ']'");
      }
    }
    if (c == '"') {
      n.type = Node::Type::kString;
      n.string = string_literal();
      return n;
    }
    if (literal("true")) {
      n.type = Node::Type::kBool;
      n.boolean = true;
      return n;
    }
    if (literal("false")) {
      n.type = Node::Type::kBool;
      return n;
    }
    if (literal("null")) return n;
    return number();
  }
  Node number() {
    // The JSON grammar: -? (0 | [1-9][0-9]*) (. [0-9]+)? ([eE] [+-]? [0-9]+)?
    const size_t start = i_;
    auto digits = [&] {
      const size_t d = i_;
      while (i_ < s_.size() && s_[i_] >= '0' && s_[i_] <= '9')
        ++i_;
      return i_ - d;
    };
    if (i_ < s_.size() && s_[i_] == '-') ++i_;
    if (i_ < s_.size() && s_[i_] == '0') {
      ++i_;
    } else if (digits() == 0) {
      fail("expected a value");
    }
    if (i_ < s_.size() && s_[i_] == '.') {
      ++i_;
      if (digits() == 0) fail("expected digits after '.'");
    }
    if (i_ < s_.size() && (s_[i_] == 'e' || s_[i_] == 'E')) {
      ++i_;
      if (i_ < s_.size() && (s_[i_] == '+' || s_[i_] == '-')) ++i_;
      if (digits() == 0) fail("expected exponent digits");
    }
    Node n;
    n.type = Node::Type::kNumber;
    n.number = std::strtod(s_.substr(start, i_ - start).c_str(), nullptr);
    return n;
  }
  std::string string_literal() {
    ++i_;  // opening quote
    std::string out;
    while (i_ < s_.size() && s_[i_] != '"') {
      const auto c = static_cast<unsigned char>(s_[i_]);
      if (c < 0x20) fail("raw control character in a string");
      if (c != '\\') {
        out += char(c);
        ++i_;
        continue;
      }
      if (++i_ >= s_.size()) fail("unterminated escape");
      const char e = s_[i_++];
      switch (e) {
        case '"':
          out += '"';
          break;
        case '\\':
          out += '\\';
          break;
        case '/':
          out += '/';
          break;
        case 'b':
          out += '\b';
          break;
        case 'f':
          out += '\f';
          break;
        case 'n':
          out += '\n';
          break;
        case 'r':
          out += '\r';
          break;
        case 't':
          out += '\t';
          break;
        case 'u': {
          if (i_ + 4 > s_.size()) fail("short \\u escape");
          const unsigned long code = std::strtoul(s_.substr(i_, 4).c_str(), nullptr, 16);
          i_ += 4;
          if (code >= 0x80) fail("test parser reads only ASCII \\u escapes");
          out += char(code);
          break;
        }
        default:
          fail("unknown escape");
      }
    }
    if (i_ >= s_.size()) fail("unterminated string");
    ++i_;
    return out;
  }

  const std::string& s_;
  size_t i_ = 0;
};

inline Node parse(const std::string& text) {
  return Parser(text).parse_document();
}

}  // namespace tandem::json_test
