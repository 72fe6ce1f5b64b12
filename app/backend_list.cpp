#include "app/backend_list.h"

#include <sstream>

#include "backends/backend_factory.h"
#include "core/util/errors.h"

namespace tandem {

std::vector<std::string> split_backend_list(const std::string& spec) {
  std::vector<std::string> names;
  std::stringstream parts(spec);
  std::string part;
  while (std::getline(parts, part, '+'))
    names.push_back(part);
  return names;
}

std::vector<std::unique_ptr<Backend>> make_backend_list(const std::string& spec,
                                                        bool validate_only) {
  std::vector<BackendKind> kinds;
  for (const std::string& name : split_backend_list(spec))
    kinds.push_back(parse_backend_kind(name));
  if (kinds.empty()) throw UsageError("--backend: empty backend list");
  if (kinds.size() > 1) {
    for (BackendKind k : kinds) {
      if (k == BackendKind::kAuto || k == BackendKind::kHetero) {
        throw UsageError("--backend " + spec + ": auto and hetero cannot be part of a list");
      }
    }
  }
  std::vector<std::unique_ptr<Backend>> out;
  if (validate_only) return out;
  BackendOptions options;
  // A GPU named beside other backends falls back to the CPU when it fails,
  // as under auto: the run goes on with the others.
  options.cuda_falls_back = kinds.size() > 1;
  for (BackendKind k : kinds) {
    for (auto& b : create_backends(k, options))
      out.push_back(std::move(b));
  }
  return out;
}

}  // namespace tandem
