// builtin:many-lights: a room lit by thousands of small emitters of varied
// power and orientation, most of them instanced, for light sampling: a
// sampler that picks lights by power alone wastes most samples on lights
// that are far away, behind a pillar or facing the wall.
#pragma once

#include "core/world/scene.h"

namespace tandem {

struct ManyLightsCounts {
  uint32_t bulbs = 1536;       // instances of one small emissive quad (2 triangles each)
  uint32_t panel_cells = 512;  // quads of one emissive mesh along a wall, 4 strengths
  uint32_t punctual = 8;       // point and spot lights
};

Scene make_many_lights_scene(const ManyLightsCounts& counts = {});

}  // namespace tandem
