// A small strict command-line parser: every option is declared, values are
// validated (whole-string numeric parses with ranges), and anything unknown
// or malformed is a UsageError (exit code 2). The options that several
// commands share are declared once, in groups (app/cli_options.h), and each
// command composes its table from them.
#pragma once

#include <cstdint>
#include <initializer_list>
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
  // The value a get_*() without a fallback uses when the option is absent,
  // and what --help shows as "(default ...)". Empty: no default (the
  // command decides, and says so in `help`).
  std::string default_value = "";
};

using OptionGroup = std::vector<OptionSpec>;

// The groups in order. A later spec of a name already present replaces the
// earlier one in its place (a command's own default or wording).
std::vector<OptionSpec> compose_options(std::initializer_list<OptionGroup> groups);

class ParsedArgs {
 public:
  // `command` prefixes every usage error ("render: ..."). "-h" is --help
  // where the table has a "help" option.
  ParsedArgs(const std::string& command, const std::vector<OptionSpec>& specs,
             const std::vector<std::string>& args);

  const std::string& command() const { return command_; }
  bool has(const std::string& name) const { return values_.count(name) != 0; }
  std::optional<std::string> value(const std::string& name) const;
  uint32_t get_u32(const std::string& name, uint32_t fallback, uint32_t min, uint32_t max) const;
  int get_int(const std::string& name, int fallback, int min, int max) const;
  float get_float(const std::string& name, float fallback, float min, float max) const;
  std::string get_string(const std::string& name, const std::string& fallback) const;
  // The same, with the default declared in the option table.
  uint32_t get_u32(const std::string& name, uint32_t min, uint32_t max) const;
  int get_int(const std::string& name, int min, int max) const;
  float get_float(const std::string& name, float min, float max) const;
  std::string get_string(const std::string& name) const;
  const std::vector<std::string>& positionals() const { return positionals_; }

 private:
  const OptionSpec& spec(const std::string& name) const;
  // The given value, or the declared default; nullopt when neither exists.
  std::optional<std::string> value_or_default(const std::string& name) const;
  uint32_t parse_u32(const std::string& name, const std::string& v, uint32_t min,
                     uint32_t max) const;
  int parse_int(const std::string& name, const std::string& v, int min, int max) const;
  float parse_float(const std::string& name, const std::string& v, float min, float max) const;

  std::string command_;
  std::vector<OptionSpec> specs_;
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
