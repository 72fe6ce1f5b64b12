// A small strict command-line parser: every option is declared, values are
// validated (whole-string numeric parses with ranges), and anything unknown
// or malformed is a UsageError (exit code 2).
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace tandem {

struct OptionSpec {
  std::string name;  // without the leading "--"
  bool takes_value;
  std::string help;
  std::string value_name = "";
};

class ParsedArgs {
 public:
  ParsedArgs(const std::string& command, const std::vector<OptionSpec>& specs,
             const std::vector<std::string>& args);

  bool has(const std::string& name) const { return values_.count(name) != 0; }
  std::optional<std::string> value(const std::string& name) const;
  uint32_t get_u32(const std::string& name, uint32_t fallback, uint32_t min, uint32_t max) const;
  int get_int(const std::string& name, int fallback, int min, int max) const;
  float get_float(const std::string& name, float fallback, float min, float max) const;
  std::string get_string(const std::string& name, const std::string& fallback) const;
  const std::vector<std::string>& positionals() const { return positionals_; }

 private:
  std::string command_;
  std::map<std::string, std::string> values_;
  std::vector<std::string> positionals_;
};

// Splits `text` at every `separator`, keeping empty items ("a,,b," -> a, "",
// b, ""), so that callers can reject them.
std::vector<std::string> split_list(const std::string& text, char separator);

// A number for messages: "1e+30", "0.5", "-50" (not 31 digits of float).
std::string format_number(double value);

std::string format_options_help(const std::vector<OptionSpec>& specs);

}  // namespace tandem
