// `tandem info SCENE`: what a scene contains.
#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "app/cli_args.h"
#include "app/cli_options.h"
#include "app/commands.h"
#include "app/render_frames.h"
#include "app/scene_setup.h"
#include "core/kernel/math.h"
#include "core/util/errors.h"
#include "core/world/scene_ranges.h"
#include "scenes/gltf_loader.h"
#include "scenes/gltf_validate.h"

namespace tandem {

namespace {
const std::vector<OptionSpec>& info_options() {
  static const std::vector<OptionSpec> specs = compose_options({scene_options(), help_options()});
  return specs;
}

bool material_emits(const Material& m) {
  return m.emissive_strength > 0.0f &&
         (m.emissive.x > 0.0f || m.emissive.y > 0.0f || m.emissive.z > 0.0f);
}
}  // namespace

int run_info(const std::vector<std::string>& argv) {
  const ParsedArgs args("info", info_options(), argv);
  if (args.has("help")) {
    std::printf("usage: tandem info SCENE [options]\n\nPrints what SCENE contains.\n\n%s",
                format_options_help(info_options()).c_str());
    return 0;
  }
  if (args.positionals().size() != 1) throw UsageError("info: expected exactly one SCENE argument");
  SceneRequest request = parse_scene_request(args, args.positionals()[0]);
  request.default_environment = false;  // info renders nothing
  GltfSummary gltf;
  request.load.gltf_summary = &gltf;
  const Scene scene = load_requested_scene(request, "tandem");

  // Emissive triangles placed, and the lights the renderer keeps for them:
  // each emissive mesh's triangles once, one per instance of one.
  size_t emissive_triangles = 0, emissive_instances = 0, mesh_lights = 0;
  std::vector<size_t> per_mesh(scene.meshes().size(), 0);
  for (size_t m = 0; m < scene.meshes().size(); ++m) {
    for (uint32_t mat : scene.meshes()[m].triangle_materials) {
      if (mat < scene.materials().size() && material_emits(scene.materials()[mat])) ++per_mesh[m];
    }
  }
  std::vector<bool> counted(per_mesh.size(), false);
  for (const Instance& inst : scene.instances()) {
    if (inst.mesh >= per_mesh.size() || per_mesh[inst.mesh] == 0) continue;
    emissive_triangles += per_mesh[inst.mesh];
    ++emissive_instances;
    if (!counted[inst.mesh]) mesh_lights += per_mesh[inst.mesh];
    counted[inst.mesh] = true;
  }
  size_t vertices = 0;
  for (const Mesh& m : scene.meshes())
    vertices += m.positions.size();
  const SceneBounds b = scene.bounds();
  std::printf("scene:      %s\n", args.positionals()[0].c_str());
  std::printf("triangles:  %zu (%zu unique in %zu meshes, %zu vertices)\n",
              scene.triangle_count_instanced(), scene.triangle_count_unique(),
              scene.meshes().size(), vertices);
  // Singular instances (a node scaled to 0) are not drawn; say how many.
  size_t hidden = 0;
  for (const Instance& inst : scene.instances()) {
    if (inst.mesh < scene.mesh_count() &&
        classify_instance(inst.transform, scene.mesh_bounds(inst.mesh)) != InstanceState::kVisible)
      ++hidden;
  }
  if (hidden == 0) {
    std::printf("instances:  %zu\n", scene.instances().size());
  } else {
    std::printf("instances:  %zu (%zu not drawn: scaled to 0 or nearly)\n",
                scene.instances().size(), hidden);
  }
  std::printf("materials:  %zu\n", scene.materials().size());
  std::printf("textures:   %zu\n", scene.textures().size());
  std::printf("lights:     %zu punctual, %zu emissive triangles%s\n", scene.lights().size(),
              emissive_triangles, scene.environment().texels.empty() ? "" : ", environment map");
  if (emissive_instances > 0) {
    std::printf("            (%zu triangle lights in the meshes, %zu emissive instances)\n",
                mesh_lights, emissive_instances);
  }
  if (b.empty) {
    std::printf("bounds:     empty\n");
  } else {
    std::printf("bounds:     (%.4g, %.4g, %.4g) - (%.4g, %.4g, %.4g), size %.4g x %.4g x %.4g\n",
                b.lo.x, b.lo.y, b.lo.z, b.hi.x, b.hi.y, b.hi.z, b.hi.x - b.lo.x, b.hi.y - b.lo.y,
                b.hi.z - b.lo.z);
  }
  if (scene.has_camera()) {
    const Camera& c = scene.camera();
    std::printf("camera:     %s at (%.4g, %.4g, %.4g) looking (%.3f, %.3f, %.3f)\n",
                c.type == CameraType::kPerspective ? "perspective" : "orthographic", c.position.x,
                c.position.y, c.position.z, c.forward.x, c.forward.y, c.forward.z);
  } else {
    std::printf("camera:     none (render frames the bounds automatically)\n");
  }
  // The file's cameras, which --camera N picks among.
  if (gltf.scene_cameras > 1) {
    std::printf("cameras:    %zu in the scene, chosen with --camera N\n", gltf.scene_cameras);
    for (size_t i = 0; i < gltf.camera_names.size(); ++i)
      std::printf("  %zu: %s\n", i, gltf.camera_names[i].c_str());
    if (gltf.camera_names.size() < gltf.scene_cameras) std::printf("  ...\n");
  }
  // The file's scenes (--gltf-scene N), animations, skins and morph targets.
  if (gltf.scenes > 1) {
    std::printf("scenes:     %zu, scene %d loaded (choose with --gltf-scene N)\n", gltf.scenes,
                gltf.scene_loaded);
    for (size_t i = 0; i < gltf.scene_names.size(); ++i)
      std::printf("  %zu: %s\n", i,
                  gltf.scene_names[i].empty() ? "(unnamed)" : gltf.scene_names[i].c_str());
    if (gltf.scene_names.size() < gltf.scenes) std::printf("  ...\n");
  }
  if (!gltf.animation_list.empty()) {
    std::printf(
        "animations: %zu (render plays them all: --frames all, or --frames A..B at --fps)\n",
        gltf.animations);
    for (size_t i = 0; i < gltf.animation_list.size(); ++i) {
      const GltfSummary::Animation& a = gltf.animation_list[i];
      // The frames `--frames all` renders at the default rate.
      std::printf("  %zu: %s, %.4g s (frames 0..%u at 24 fps), %zu channels\n", i,
                  a.name.empty() ? "(unnamed)" : a.name.c_str(), a.seconds,
                  last_frame_within(a.seconds, RenderFrames{}.fps), a.channels);
    }
    if (gltf.animation_list.size() < gltf.animations) std::printf("  ...\n");
  }
  if (!gltf.skin_list.empty()) {
    std::printf("skins:      %zu\n", gltf.skins);
    for (size_t i = 0; i < gltf.skin_list.size(); ++i)
      std::printf("  %zu: %s, %zu joints\n", i,
                  gltf.skin_list[i].name.empty() ? "(unnamed)" : gltf.skin_list[i].name.c_str(),
                  gltf.skin_list[i].joints);
    if (gltf.skin_list.size() < gltf.skins) std::printf("  ...\n");
  }
  if (gltf.morph_meshes > 0) {
    std::printf("morphs:     %zu meshes with morph targets (up to %zu targets)\n",
                gltf.morph_meshes, gltf.most_morph_targets);
  }
  // The file's extensions and what becomes of each here.
  if (!gltf.extensions_used.empty() || !gltf.extensions_required.empty()) {
    std::vector<std::string> names = gltf.extensions_used;
    for (const std::string& r : gltf.extensions_required)
      if (std::find(names.begin(), names.end(), r) == names.end()) names.push_back(r);
    std::printf("extensions:");
    for (size_t i = 0; i < names.size(); ++i) {
      const std::string& e = names[i];
      const bool required =
          std::find(gltf.extensions_required.begin(), gltf.extensions_required.end(), e) !=
          gltf.extensions_required.end();
      const char* status = gltf::extension_supported(e)   ? "supported"
                           : gltf::extension_ignorable(e) ? "not modelled, the rest loads"
                                                          : "not supported, ignored";
      std::printf("%s %s (%s%s)", i ? "," : "", e.c_str(), required ? "required, " : "", status);
    }
    std::printf("\n");
  }
  return 0;
}

}  // namespace tandem
