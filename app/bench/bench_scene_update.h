// `tandem bench [SCENE...] --scene-update`: what a small scene edit costs in
// the per-frame update path (SyncScene + UpdateAccStruc), for the edits a
// game makes every frame: one instance moved, a hundred moved, one material
// changed, one light changed.
#pragma once

#include <string>
#include <vector>

namespace tandem {

// Whether `args` ask for this benchmark (they contain --scene-update).
bool is_scene_update_bench(const std::vector<std::string>& args);
int run_scene_update_bench(const std::vector<std::string>& args);

}  // namespace tandem
