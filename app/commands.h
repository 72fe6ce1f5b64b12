// Subcommands of the `tandem` executable. Each returns the process exit code
// and throws UsageError (exit 2) or InputError (exit 1) on bad input.
#pragma once

#include <string>
#include <vector>

namespace tandem {

int run_render(const std::vector<std::string>& args);
int run_info(const std::vector<std::string>& args);
int run_export(const std::vector<std::string>& args);
int run_compare(const std::vector<std::string>& args);
int run_bench(const std::vector<std::string>& args);
void print_render_help();

}  // namespace tandem
