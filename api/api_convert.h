// Checks and conversions between the public API's plain structs and the
// engine's scene model. Every check throws tandem::Error(kInvalidArgument)
// whose message names the function, the field and the reason, so a bad value
// from a game never reaches the scene compiler or a kernel.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "api/tandem/tandem.h"
#include "core/world/scene.h"

namespace tandem::api_detail {

[[noreturn]] void invalid(const std::string& message);

// `what` names the call in messages, e.g. "add_mesh".
Mesh to_mesh(const MeshData& data, uint32_t material, const char* what);
// `texture_peaks`: per texture of the scene, its largest texel value (1 for
// 8-bit ones): the ids are checked against it, and emission times an
// emission texture's peak must stay within what can be rendered.
Material to_material(const MaterialDesc& desc, const std::vector<float>& texture_peaks,
                     const char* what);
// `peak`: set to the largest texel value (1 for 8-bit textures).
Texture to_texture(const TextureDesc& desc, const char* what, float* peak);
Light to_light(const LightDesc& desc, const char* what);
// The image's aspect ratio comes from the render settings, not the camera.
Camera to_camera(const CameraDesc& desc, const char* what);
glm::mat4 to_matrix(const Transform& transform, const char* what);
void check_options(const RendererOptions& options, const char* what);

// `vertices` (positions, and normals/uvs where given), checked, as a pose
// of a mesh of `mesh_vertices` vertices (Scene::pose_mesh): the compiler
// converts them straight into the kernel arrays, so a game's deforming mesh
// is copied once on its way to the renderers, as a skinned glTF mesh is.
std::shared_ptr<const MeshPose> vertices_pose(const MeshData& vertices, size_t mesh_vertices,
                                              const char* what);

}  // namespace tandem::api_detail
