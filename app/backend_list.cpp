#include "app/backend_list.h"

#include "backends/backend_factory.h"
#include "core/util/errors.h"

namespace tandem {

std::vector<std::string> split_backend_list(const std::string& spec) {
  // Empty items are kept ("cpu+" -> cpu, ""), so parse_backend_list can
  // refuse them instead of reading "cpu+" as "cpu".
  std::vector<std::string> names;
  size_t start = 0;
  while (true) {
    const size_t at = spec.find('+', start);
    names.push_back(spec.substr(start, at == std::string::npos ? std::string::npos : at - start));
    if (at == std::string::npos) return names;
    start = at + 1;
  }
}

// Messages name the list, not an option: the same list comes from
// `render --backend` and from `bench --hetero`.
std::vector<BackendKind> parse_backend_list(const std::string& spec) {
  if (spec.empty()) {
    throw UsageError("the backend list is empty (expected e.g. cpu, hetero or cpu+host)");
  }
  std::vector<BackendKind> kinds;
  for (const std::string& name : split_backend_list(spec)) {
    if (name.empty()) {
      throw UsageError("backend list '" + spec +
                       "' has an empty name (a '+' at the start or end, or two in a row)");
    }
    kinds.push_back(parse_backend_kind(name));
  }
  if (kinds.size() > 1) {
    for (BackendKind k : kinds) {
      if (k == BackendKind::kAuto || k == BackendKind::kHetero) {
        throw UsageError("backend list '" + spec + "': auto and hetero cannot be part of a list");
      }
    }
  }
  return kinds;
}

std::vector<std::unique_ptr<Backend>> make_backend_list(const std::string& spec,
                                                        const BackendOptions& options,
                                                        bool validate_only) {
  const std::vector<BackendKind> kinds = parse_backend_list(spec);
  std::vector<std::unique_ptr<Backend>> out;
  if (validate_only) return out;
  // A GPU named beside other backends falls back to the CPU when it fails,
  // as under auto: the run goes on with the others.
  BackendOptions list_options = options;
  list_options.cuda_falls_back = kinds.size() > 1;
  for (BackendKind k : kinds) {
    for (auto& b : create_backends(k, list_options))
      out.push_back(std::move(b));
  }
  return out;
}

BackendOptions parse_kernel_option(const std::optional<std::string>& kernel,
                                   const std::vector<BackendKind>& kinds) {
  BackendOptions options;
  if (!kernel) return options;
  try {
    options.kernel = parse_cuda_kernel_variant(*kernel);
  } catch (const UsageError& e) {
    throw UsageError(std::string("--kernel: ") + e.what());
  }
  (void)kinds;  // every backend has both kernels now
  return options;
}

}  // namespace tandem
