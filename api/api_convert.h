// Checks and conversions between the public API's plain structs and the
// engine's scene model. Every check throws tandem::Error(kInvalidArgument)
// whose message names the function, the field and the reason, so a bad value
// from a game never reaches the scene compiler or a kernel.
#pragma once

#include <string>

#include "api/tandem/tandem.h"
#include "core/world/scene.h"

namespace tandem::api_detail {

[[noreturn]] void invalid(const std::string& message);

// `what` names the call in messages, e.g. "add_mesh".
Mesh to_mesh(const MeshData& data, uint32_t material, const char* what);
Material to_material(const MaterialDesc& desc, const char* what);
Light to_light(const LightDesc& desc, const char* what);
// The image's aspect ratio comes from the render settings, not the camera.
Camera to_camera(const CameraDesc& desc, const char* what);
glm::mat4 to_matrix(const Transform& transform, const char* what);
void check_options(const RendererOptions& options, const char* what);

// Writes `vertices` (positions, and normals/uvs where given) over `mesh`,
// whose vertex count it must match.
void overwrite_vertices(const MeshData& vertices, Mesh& mesh, const char* what);

}  // namespace tandem::api_detail
