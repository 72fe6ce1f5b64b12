#include "app/view/motion_quality.h"

#include "app/view/image_filters.h"
#include "backends/backend_factory.h"
#include "core/render/offline_render.h"
#include "sync/scene_sync.h"

namespace tandem {

double motion_relmse(const Scene& frame, const ViewSession& session, uint32_t reference_spp) {
  const ViewOptions& o = session.options();
  Scene scene = frame;  // compiled from scratch; the caller's keeps its dirty flags
  RenderSettings settings;
  settings.width = o.width;
  settings.height = o.height;
  settings.max_depth = o.max_depth;
  settings.seed = 0x5eed0001u;  // samples of its own, not the frame's
  std::vector<std::unique_ptr<Backend>> backends = create_backends(BackendKind::kCpu, {});
  Backend& backend = *backends.front();
  SceneSync sync(SceneSyncSettings::arrays_only());
  backend.sync(sync.kernel_scene(), sync.update(scene, settings).changes);
  OfflineRenderOptions render;
  render.spp = reference_spp;
  const ImageRGB reference = render_offline(backend, o.width, o.height, render).image;
  return relative_mse(resize_linear(session.shown_linear(), o.width, o.height), reference);
}

}  // namespace tandem
