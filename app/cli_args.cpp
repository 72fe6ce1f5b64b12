#include "app/cli_args.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

#include "core/util/errors.h"

namespace tandem {

std::vector<OptionSpec> compose_options(std::initializer_list<OptionGroup> groups) {
  std::vector<OptionSpec> out;
  for (const OptionGroup& group : groups) {
    for (const OptionSpec& s : group) {
      auto same = std::find_if(out.begin(), out.end(),
                               [&](const OptionSpec& o) { return o.name == s.name; });
      if (same != out.end()) {
        *same = s;
      } else {
        out.push_back(s);
      }
    }
  }
  return out;
}

ParsedArgs::ParsedArgs(const std::string& command, const std::vector<OptionSpec>& specs,
                       const std::vector<std::string>& args)
    : command_(command), specs_(specs) {
  const bool has_help =
      std::any_of(specs.begin(), specs.end(), [](const OptionSpec& s) { return s.name == "help"; });
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "-h" && has_help) {
      values_["help"] = "";
      continue;
    }
    if (a.size() < 2 || a.compare(0, 2, "--") != 0 || a == "--") {
      if (a == "--") {
        positionals_.insert(positionals_.end(), args.begin() + long(i) + 1, args.end());
        break;
      }
      if (a.size() > 1 && a[0] == '-' && !(a[1] >= '0' && a[1] <= '9')) {
        throw UsageError(command_ + ": unknown option '" + a + "'");
      }
      positionals_.push_back(a);
      continue;
    }
    std::string name = a.substr(2), value;
    bool inline_value = false;
    if (const size_t eq = name.find('='); eq != std::string::npos) {
      value = name.substr(eq + 1);
      name = name.substr(0, eq);
      inline_value = true;
    }
    const OptionSpec* spec = nullptr;
    for (const OptionSpec& s : specs) {
      if (s.name == name) spec = &s;
    }
    if (!spec) throw UsageError(command_ + ": unknown option '--" + name + "'");
    if (spec->takes_value && !inline_value) {
      if (i + 1 >= args.size())
        throw UsageError(command_ + ": option '--" + name + "' needs a value");
      value = args[++i];
    } else if (!spec->takes_value && inline_value) {
      throw UsageError(command_ + ": option '--" + name + "' takes no value");
    }
    if (values_.count(name)) throw UsageError(command_ + ": option '--" + name + "' given twice");
    values_[name] = value;
  }
}

std::optional<std::string> ParsedArgs::value(const std::string& name) const {
  auto it = values_.find(name);
  if (it == values_.end()) return std::nullopt;
  return it->second;
}

const OptionSpec& ParsedArgs::spec(const std::string& name) const {
  for (const OptionSpec& s : specs_) {
    if (s.name == name) return s;
  }
  // A programming error, not the user's: every option read must be declared.
  throw std::logic_error(command_ + ": option '--" + name + "' is not in the option table");
}

std::optional<std::string> ParsedArgs::value_or_default(const std::string& name) const {
  if (auto v = value(name)) return v;
  const OptionSpec& s = spec(name);
  if (s.default_value.empty()) return std::nullopt;
  return s.default_value;
}

std::string ParsedArgs::get_string(const std::string& name, const std::string& fallback) const {
  return value(name).value_or(fallback);
}

std::string ParsedArgs::get_string(const std::string& name) const {
  return value_or_default(name).value_or("");
}

int ParsedArgs::get_int(const std::string& name, int fallback, int min, int max) const {
  const auto v = value(name);
  return v ? parse_int(name, *v, min, max) : fallback;
}

int ParsedArgs::get_int(const std::string& name, int min, int max) const {
  const auto v = value_or_default(name);
  return v ? parse_int(name, *v, min, max) : 0;
}

uint32_t ParsedArgs::get_u32(const std::string& name, uint32_t fallback, uint32_t min,
                             uint32_t max) const {
  const auto v = value(name);
  return v ? parse_u32(name, *v, min, max) : fallback;
}

uint32_t ParsedArgs::get_u32(const std::string& name, uint32_t min, uint32_t max) const {
  const auto v = value_or_default(name);
  return v ? parse_u32(name, *v, min, max) : 0;
}

float ParsedArgs::get_float(const std::string& name, float fallback, float min, float max) const {
  const auto v = value(name);
  return v ? parse_float(name, *v, min, max) : fallback;
}

float ParsedArgs::get_float(const std::string& name, float min, float max) const {
  const auto v = value_or_default(name);
  return v ? parse_float(name, *v, min, max) : 0.0f;
}

int ParsedArgs::parse_int(const std::string& name, const std::string& text, int min,
                          int max) const {
  const std::string* v = &text;
  errno = 0;
  char* end = nullptr;
  const long n = std::strtol(v->c_str(), &end, 10);
  if (v->empty() || *end != '\0' || errno == ERANGE || n < min || n > max) {
    throw UsageError(command_ + ": --" + name + " expects an integer in [" + std::to_string(min) +
                     ", " + std::to_string(max) + "], got '" + *v + "'");
  }
  return int(n);
}

uint32_t ParsedArgs::parse_u32(const std::string& name, const std::string& text, uint32_t min,
                               uint32_t max) const {
  const std::string* v = &text;
  errno = 0;
  char* end = nullptr;
  const unsigned long long n = std::strtoull(v->c_str(), &end, 10);
  if (v->empty() || (*v)[0] == '-' || *end != '\0' || errno == ERANGE || n < min || n > max) {
    throw UsageError(command_ + ": --" + name + " expects an integer in [" + std::to_string(min) +
                     ", " + std::to_string(max) + "], got '" + *v + "'");
  }
  return uint32_t(n);
}

float ParsedArgs::parse_float(const std::string& name, const std::string& text, float min,
                              float max) const {
  const std::string* v = &text;
  errno = 0;
  char* end = nullptr;
  // Parsed as double: a tiny value such as 1e-50 underflows float (ERANGE)
  // but is a perfectly good request for 0.
  const double d = std::strtod(v->c_str(), &end);
  const bool overflow = errno == ERANGE && std::fabs(d) > 1.0;
  if (v->empty() || *end != '\0' || overflow || !std::isfinite(d) || d < double(min) ||
      d > double(max)) {
    throw UsageError(command_ + ": --" + name + " expects a number in [" + format_number(min) +
                     ", " + format_number(max) + "], got '" + *v + "'");
  }
  return float(d);
}

std::vector<std::string> split_list(const std::string& text, char separator) {
  std::vector<std::string> items;
  size_t start = 0;
  while (true) {
    const size_t at = text.find(separator, start);
    items.push_back(text.substr(start, at == std::string::npos ? std::string::npos : at - start));
    if (at == std::string::npos) return items;
    start = at + 1;
  }
}

std::string format_number(double value) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", value);
  return buf;
}

std::string format_options_help(const std::vector<OptionSpec>& specs) {
  std::string out;
  for (const OptionSpec& s : specs) {
    std::string left =
        "  --" + s.name + (s.takes_value ? " " + (s.value_name.empty() ? "X" : s.value_name) : "");
    if (left.size() < 28)
      left.resize(28, ' ');
    else
      left += "  ";
    out += left + s.help;
    if (!s.default_value.empty()) out += " (default " + s.default_value + ")";
    out += "\n";
  }
  return out;
}

}  // namespace tandem
