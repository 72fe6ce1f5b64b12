#include "scenes/gltf_validate.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string_view>

namespace tandem::gltf {

namespace {

using tinygltf::Model;

std::string str(size_t v) {
  return std::to_string(v);
}
std::string str(int v) {
  return std::to_string(v);
}

// "accessor 7 refers to bufferView 12, but the file has 3 bufferViews".
void check_ref(const Context& ctx, int index, size_t size, bool optional, const std::string& who,
               const char* kind) {
  if (optional && index == -1) return;
  if (index < 0 || size_t(index) >= size) {
    ctx.fail(who + " refers to " + kind + " " + str(index) + ", but the file has " + str(size) +
             " " + kind + (size == 1 ? "" : "s"));
  }
}

// Integral values print without decimals ("-1", not "-1.000000").
std::string number_text(double v) {
  if (std::isfinite(v) && v == std::floor(v) && std::fabs(v) < 1e15)
    return std::to_string(int64_t(v));
  return std::to_string(v);
}

bool finite_all(const std::vector<double>& v) {
  return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
}

// a + b and a * b on 64 bits, failing instead of wrapping.
bool add_ok(uint64_t a, uint64_t b, uint64_t& out) {
  return !__builtin_add_overflow(a, b, &out);
}
bool mul_ok(uint64_t a, uint64_t b, uint64_t& out) {
  return !__builtin_mul_overflow(a, b, &out);
}

// True when `count` elements of `element` bytes, `stride` apart, starting at
// `offset`, end within `limit` bytes.
bool range_fits(uint64_t offset, uint64_t stride, uint64_t count, uint64_t element,
                uint64_t limit) {
  if (count == 0) return offset <= limit;
  uint64_t span = 0, end = 0;
  if (!mul_ok(stride, count - 1, span) || !add_ok(span, element, span) ||
      !add_ok(offset, span, end)) {
    return false;
  }
  return end <= limit;
}

const char* component_name(int ct) {
  switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
      return "BYTE";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return "UNSIGNED_BYTE";
    case TINYGLTF_COMPONENT_TYPE_SHORT:
      return "SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return "UNSIGNED_SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
      return "UNSIGNED_INT";
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return "FLOAT";
    default:
      return "invalid";
  }
}

const char* type_name(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return "SCALAR";
    case TINYGLTF_TYPE_VEC2:
      return "VEC2";
    case TINYGLTF_TYPE_VEC3:
      return "VEC3";
    case TINYGLTF_TYPE_VEC4:
      return "VEC4";
    case TINYGLTF_TYPE_MAT2:
      return "MAT2";
    case TINYGLTF_TYPE_MAT3:
      return "MAT3";
    case TINYGLTF_TYPE_MAT4:
      return "MAT4";
    default:
      return "invalid";
  }
}

std::string format_name(const tinygltf::Accessor& a) {
  return std::string(type_name(a.type)) + " " + component_name(a.componentType) +
         (a.normalized ? " (normalized)" : "");
}

void validate_buffer_views(const Context& ctx) {
  const Model& m = ctx.model;
  for (size_t i = 0; i < m.bufferViews.size(); ++i) {
    const tinygltf::BufferView& v = m.bufferViews[i];
    const std::string who = "bufferView " + str(i);
    check_ref(ctx, v.buffer, m.buffers.size(), false, who, "buffer");
    const size_t size = m.buffers[size_t(v.buffer)].data.size();
    if (v.byteLength < 1) ctx.fail(who + " has byteLength 0");
    if (!range_fits(v.byteOffset, 0, 1, v.byteLength, size)) {
      ctx.fail(who + " (byteOffset " + str(v.byteOffset) + ", byteLength " + str(v.byteLength) +
               ") runs past the end of buffer " + str(v.buffer) + " (" + str(size) + " bytes)");
    }
    if (v.byteStride != 0 && (v.byteStride < 4 || v.byteStride > 252 || v.byteStride % 4 != 0)) {
      ctx.fail(who + " has byteStride " + str(v.byteStride) +
               " (must be a multiple of 4 in 4..252)");
    }
  }
}

void validate_sparse(const Context& ctx, const tinygltf::Accessor& a, const std::string& who) {
  const Model& m = ctx.model;
  const auto& s = a.sparse;
  if (s.count < 1 || size_t(s.count) > a.count) {
    ctx.fail(who + " has sparse.count " + str(s.count) + " (must be 1.." + str(a.count) + ")");
  }
  check_ref(ctx, s.indices.bufferView, m.bufferViews.size(), false, who + " sparse.indices",
            "bufferView");
  check_ref(ctx, s.values.bufferView, m.bufferViews.size(), false, who + " sparse.values",
            "bufferView");
  const int ict = s.indices.componentType;
  if (ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
      ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
      ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
    ctx.fail(who + " has sparse indices of componentType " + str(ict) +
             " (must be UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT)");
  }
  if (s.indices.byteOffset < 0 || s.values.byteOffset < 0) {
    ctx.fail(who + " has a negative sparse byteOffset");
  }
  const size_t isize = component_size(ict);
  const auto& iview = m.bufferViews[size_t(s.indices.bufferView)];
  if (!range_fits(uint64_t(s.indices.byteOffset), isize, uint64_t(s.count), isize,
                  iview.byteLength)) {
    ctx.fail(who + " sparse indices run past the end of bufferView " + str(s.indices.bufferView));
  }
  if ((iview.byteOffset + uint64_t(s.indices.byteOffset)) % isize != 0) {
    ctx.fail(who + " sparse indices are not aligned to their component size");
  }
  const size_t esize = accessor_element_size(a.componentType, a.type);
  const auto& vview = m.bufferViews[size_t(s.values.bufferView)];
  if (!range_fits(uint64_t(s.values.byteOffset), esize, uint64_t(s.count), esize,
                  vview.byteLength)) {
    ctx.fail(who + " sparse values run past the end of bufferView " + str(s.values.bufferView));
  }
  if ((vview.byteOffset + uint64_t(s.values.byteOffset)) % component_size(a.componentType) != 0) {
    ctx.fail(who + " sparse values are not aligned to their component size");
  }
}

void validate_accessors(const Context& ctx) {
  const Model& m = ctx.model;
  for (size_t i = 0; i < m.accessors.size(); ++i) {
    const tinygltf::Accessor& a = m.accessors[i];
    const std::string who = "accessor " + str(i);
    const size_t csize = component_size(a.componentType);
    if (csize == 0) ctx.fail(who + " has invalid componentType " + str(a.componentType));
    if (component_count(a.type) == 0) ctx.fail(who + " has an invalid type");
    if (a.normalized && (a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT ||
                         a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)) {
      ctx.fail(who + " is normalized but has componentType " + component_name(a.componentType));
    }
    if (a.count < 1) ctx.fail(who + " has count 0");
    const size_t esize = accessor_element_size(a.componentType, a.type);
    if (a.bufferView == -1) {
      // All zeros (possibly with sparse values): nothing in the file bounds
      // the count, so cap it (the decoder also counts all such accessors
      // together against the same limit).
      if (a.count > ctx.limits.max_zero_filled_elements) {
        ctx.fail(who + " has no bufferView and count " + str(a.count) + " (limit " +
                 str(size_t(ctx.limits.max_zero_filled_elements)) + ")");
      }
    } else {
      check_ref(ctx, a.bufferView, m.bufferViews.size(), false, who, "bufferView");
      const tinygltf::BufferView& v = m.bufferViews[size_t(a.bufferView)];
      const size_t stride = v.byteStride != 0 ? v.byteStride : esize;
      if (stride < esize) {
        ctx.fail(who + " has elements of " + str(esize) + " bytes but bufferView " +
                 str(a.bufferView) + " has byteStride " + str(v.byteStride));
      }
      if ((v.byteOffset + uint64_t(a.byteOffset)) % csize != 0 || stride % csize != 0) {
        ctx.fail(who + " is not aligned to its component size (" + str(csize) + " bytes)");
      }
      if (!range_fits(a.byteOffset, stride, a.count, esize, v.byteLength)) {
        ctx.fail(who + " (byteOffset " + str(a.byteOffset) + ", count " + str(a.count) +
                 ", stride " + str(stride) + ") runs past the end of bufferView " +
                 str(a.bufferView) + " (" + str(v.byteLength) + " bytes)");
      }
    }
    if (a.sparse.isSparse) validate_sparse(ctx, a, who);
  }
}

// Checks an attribute accessor's type/componentType against the glTF 2.0
// rules for its semantic. Application-specific ("_FOO") and unknown
// semantics are not restricted.
void check_attribute_format(const Context& ctx, const std::string& semantic,
                            const tinygltf::Accessor& a, const std::string& who) {
  const int ct = a.componentType;
  const bool f = ct == TINYGLTF_COMPONENT_TYPE_FLOAT && !a.normalized;
  const bool un8_16 = a.normalized && (ct == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
                                       ct == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT);
  auto starts = [&](std::string_view p) { return semantic.rfind(p, 0) == 0; };
  bool ok = true;
  std::string need;
  if (semantic == "POSITION" || semantic == "NORMAL") {
    ok = a.type == TINYGLTF_TYPE_VEC3 && f;
    need = "VEC3 FLOAT";
  } else if (semantic == "TANGENT") {
    ok = a.type == TINYGLTF_TYPE_VEC4 && f;
    need = "VEC4 FLOAT";
  } else if (starts("TEXCOORD_")) {
    ok = a.type == TINYGLTF_TYPE_VEC2 && (f || un8_16);
    need = "VEC2 FLOAT or normalized UNSIGNED_BYTE/UNSIGNED_SHORT";
  } else if (starts("COLOR_")) {
    ok = (a.type == TINYGLTF_TYPE_VEC3 || a.type == TINYGLTF_TYPE_VEC4) && (f || un8_16);
    need = "VEC3/VEC4 FLOAT or normalized UNSIGNED_BYTE/UNSIGNED_SHORT";
  } else if (starts("JOINTS_")) {
    ok = a.type == TINYGLTF_TYPE_VEC4 && !a.normalized &&
         (ct == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
          ct == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT);
    need = "VEC4 UNSIGNED_BYTE/UNSIGNED_SHORT";
  } else if (starts("WEIGHTS_")) {
    ok = a.type == TINYGLTF_TYPE_VEC4 && (f || un8_16);
    need = "VEC4 FLOAT or normalized UNSIGNED_BYTE/UNSIGNED_SHORT";
  }
  if (!ok) ctx.fail(who + ": " + semantic + " must be " + need + ", but is " + format_name(a));
}

void validate_meshes(const Context& ctx) {
  const Model& m = ctx.model;
  for (size_t mi = 0; mi < m.meshes.size(); ++mi) {
    const tinygltf::Mesh& mesh = m.meshes[mi];
    if (mesh.primitives.empty()) {
      ctx.fail("mesh " + str(mi) + " has no primitives (\"primitives\" must be a non-empty array)");
    }
    for (size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
      const tinygltf::Primitive& p = mesh.primitives[pi];
      const std::string who = "mesh " + str(mi) + " primitive " + str(pi);
      if (p.mode < TINYGLTF_MODE_POINTS || p.mode > TINYGLTF_MODE_TRIANGLE_FAN) {
        ctx.fail(who + " has invalid mode " + str(p.mode));
      }
      check_ref(ctx, p.material, m.materials.size(), true, who, "material");
      const auto position = p.attributes.find("POSITION");
      if (position == p.attributes.end()) ctx.fail(who + " has no POSITION attribute");
      check_ref(ctx, position->second, m.accessors.size(), false, who + " attribute POSITION",
                "accessor");
      const size_t vertex_count = m.accessors[size_t(position->second)].count;
      for (const auto& [semantic, index] : p.attributes) {
        check_ref(ctx, index, m.accessors.size(), false, who + " attribute " + semantic,
                  "accessor");
        const tinygltf::Accessor& a = m.accessors[size_t(index)];
        check_attribute_format(ctx, semantic, a, who);
        if (a.count != vertex_count) {
          ctx.fail(who + ": attribute " + semantic + " has " + str(a.count) +
                   " elements but POSITION has " + str(vertex_count) +
                   " (all attributes of a primitive must have the same count)");
        }
      }
      if (p.indices != -1) {
        check_ref(ctx, p.indices, m.accessors.size(), false, who + " indices", "accessor");
        const tinygltf::Accessor& a = m.accessors[size_t(p.indices)];
        const int ct = a.componentType;
        if (a.type != TINYGLTF_TYPE_SCALAR || a.normalized ||
            (ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
             ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
             ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)) {
          ctx.fail(who +
                   ": indices must be SCALAR UNSIGNED_BYTE/UNSIGNED_SHORT/UNSIGNED_INT, but are " +
                   format_name(a));
        }
      }
      // Morph weights are one list per mesh, so every primitive needs the
      // same number of targets.
      if (p.targets.size() != mesh.primitives.front().targets.size()) {
        ctx.fail(who + " has " + str(p.targets.size()) + " morph targets but primitive 0 has " +
                 str(mesh.primitives.front().targets.size()) +
                 " (all primitives of a mesh must have the same number)");
      }
      for (size_t t = 0; t < p.targets.size(); ++t) {
        for (const auto& [semantic, index] : p.targets[t]) {
          const std::string twho = who + " morph target " + str(t) + " " + semantic;
          check_ref(ctx, index, m.accessors.size(), false, twho, "accessor");
          const tinygltf::Accessor& a = m.accessors[size_t(index)];
          if (a.count != vertex_count) {
            ctx.fail(twho + " has a different count than POSITION");
          }
          // Deltas of the attributes that are deformed; others are ignored.
          if ((semantic == "POSITION" || semantic == "NORMAL" || semantic == "TANGENT") &&
              a.type != TINYGLTF_TYPE_VEC3) {
            ctx.fail(twho + " must be VEC3, but is " + format_name(a));
          }
        }
      }
    }
    const size_t targets = mesh.primitives.front().targets.size();
    if (!mesh.weights.empty() && mesh.weights.size() != targets) {
      ctx.fail("mesh " + str(mi) + " has " + str(mesh.weights.size()) + " weights but " +
               str(targets) + " morph targets");
    }
    if (!finite_all(mesh.weights)) ctx.fail("mesh " + str(mi) + " has a weight that is not finite");
  }
}

// Texture references: tinygltf's TextureInfo cannot tell "absent" from an
// explicit "index": -1, but its legacy ParameterMaps keep every number
// written in the JSON object, so an explicit negative index shows up there.
void check_legacy_texture_params(const Context& ctx, const tinygltf::ParameterMap& params,
                                 const std::string& who) {
  for (const auto& [key, param] : params) {
    const auto it = param.json_double_value.find("index");
    if (it == param.json_double_value.end()) continue;
    const double idx = it->second;
    if (!(idx >= 0.0) || idx != std::floor(idx) || idx >= double(ctx.model.textures.size())) {
      ctx.fail(who + " " + key + " has texture index " + number_text(idx) + ", but the file has " +
               str(ctx.model.textures.size()) + " textures");
    }
  }
}

void check_texture_info(const Context& ctx, int index, int tex_coord, const std::string& who) {
  check_ref(ctx, index, ctx.model.textures.size(), true, who, "texture");
  if (tex_coord < 0) ctx.fail(who + " has negative texCoord " + str(tex_coord));
}

// Texture objects inside material extensions (KHR_materials_*): any
// "...Texture" member must be an object with a valid integer index.
void check_extension_textures(const Context& ctx, const tinygltf::Value& v,
                              const std::string& who) {
  if (!v.IsObject()) return;
  for (const std::string& key : v.Keys()) {
    const tinygltf::Value& child = v.Get(key);
    const bool is_texture = key.size() > 7 && key.compare(key.size() - 7, 7, "Texture") == 0;
    if (is_texture) {
      const std::string twho = who + " " + key;
      if (!child.IsObject() || !child.Has("index") || !child.Get("index").IsInt()) {
        ctx.fail(twho + " has no integer \"index\"");
      }
      check_texture_info(ctx, child.Get("index").Get<int>(), 0, twho);
      if (child.Has("texCoord") &&
          (!child.Get("texCoord").IsInt() || child.Get("texCoord").Get<int>() < 0)) {
        ctx.fail(twho + " has an invalid texCoord");
      }
    } else if (child.IsObject()) {
      check_extension_textures(ctx, child, who);
    }
  }
}

void validate_materials(const Context& ctx) {
  const Model& m = ctx.model;
  for (size_t i = 0; i < m.materials.size(); ++i) {
    const tinygltf::Material& mat = m.materials[i];
    const std::string who = "material " + str(i);
    const auto& pbr = mat.pbrMetallicRoughness;
    check_texture_info(ctx, pbr.baseColorTexture.index, pbr.baseColorTexture.texCoord,
                       who + " baseColorTexture");
    check_texture_info(ctx, pbr.metallicRoughnessTexture.index,
                       pbr.metallicRoughnessTexture.texCoord, who + " metallicRoughnessTexture");
    check_texture_info(ctx, mat.normalTexture.index, mat.normalTexture.texCoord,
                       who + " normalTexture");
    check_texture_info(ctx, mat.occlusionTexture.index, mat.occlusionTexture.texCoord,
                       who + " occlusionTexture");
    check_texture_info(ctx, mat.emissiveTexture.index, mat.emissiveTexture.texCoord,
                       who + " emissiveTexture");
    check_legacy_texture_params(ctx, mat.values, who);
    check_legacy_texture_params(ctx, mat.additionalValues, who);
    for (const auto& [name, ext] : mat.extensions) {
      check_extension_textures(ctx, ext, who + " " + name);
    }
    if (pbr.baseColorFactor.size() != 4 || !finite_all(pbr.baseColorFactor)) {
      ctx.fail(who + " baseColorFactor must be 4 finite numbers");
    }
    if (mat.emissiveFactor.size() != 3 || !finite_all(mat.emissiveFactor)) {
      ctx.fail(who + " emissiveFactor must be 3 finite numbers");
    }
    if (!std::isfinite(pbr.metallicFactor) || !std::isfinite(pbr.roughnessFactor) ||
        !std::isfinite(mat.normalTexture.scale) || !std::isfinite(mat.occlusionTexture.strength)) {
      ctx.fail(who + " has a non-finite factor");
    }
    if (mat.alphaMode != "OPAQUE" && mat.alphaMode != "MASK" && mat.alphaMode != "BLEND") {
      ctx.fail(who + " has alphaMode \"" + mat.alphaMode + "\" (must be OPAQUE, MASK or BLEND)");
    }
    if (!std::isfinite(mat.alphaCutoff) || mat.alphaCutoff < 0.0) {
      ctx.fail(who + " has alphaCutoff " + std::to_string(mat.alphaCutoff) + " (must be >= 0)");
    }
  }
}

void validate_textures(const Context& ctx) {
  const Model& m = ctx.model;
  for (size_t i = 0; i < m.images.size(); ++i) {
    check_ref(ctx, m.images[i].bufferView, m.bufferViews.size(), true, "image " + str(i),
              "bufferView");
  }
  for (size_t i = 0; i < m.textures.size(); ++i) {
    const std::string who = "texture " + str(i);
    check_ref(ctx, m.textures[i].source, m.images.size(), true, who, "image");
    check_ref(ctx, m.textures[i].sampler, m.samplers.size(), true, who, "sampler");
  }
  for (size_t i = 0; i < m.samplers.size(); ++i) {
    const tinygltf::Sampler& s = m.samplers[i];
    const std::string who = "sampler " + str(i);
    auto wrap_ok = [](int w) {
      return w == TINYGLTF_TEXTURE_WRAP_REPEAT || w == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE ||
             w == TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT;
    };
    if (!wrap_ok(s.wrapS) || !wrap_ok(s.wrapT)) ctx.fail(who + " has an invalid wrapS/wrapT value");
    if (s.magFilter != -1 && s.magFilter != TINYGLTF_TEXTURE_FILTER_NEAREST &&
        s.magFilter != TINYGLTF_TEXTURE_FILTER_LINEAR) {
      ctx.fail(who + " has invalid magFilter " + str(s.magFilter));
    }
    if (s.minFilter != -1 && s.minFilter != TINYGLTF_TEXTURE_FILTER_NEAREST &&
        s.minFilter != TINYGLTF_TEXTURE_FILTER_LINEAR &&
        (s.minFilter < TINYGLTF_TEXTURE_FILTER_NEAREST_MIPMAP_NEAREST ||
         s.minFilter > TINYGLTF_TEXTURE_FILTER_LINEAR_MIPMAP_LINEAR)) {
      ctx.fail(who + " has invalid minFilter " + str(s.minFilter));
    }
  }
}

void validate_cameras_and_lights(const Context& ctx) {
  const Model& m = ctx.model;
  for (size_t i = 0; i < m.cameras.size(); ++i) {
    const tinygltf::Camera& c = m.cameras[i];
    const std::string who = "camera " + str(i);
    if (c.type == "perspective") {
      const auto& p = c.perspective;
      if (!(std::isfinite(p.yfov) && p.yfov > 0.0 && p.yfov < std::numbers::pi)) {
        ctx.fail(who + " has yfov " + std::to_string(p.yfov) + " (must be in (0, pi))");
      }
      if (!std::isfinite(p.znear) || !std::isfinite(p.zfar) || !std::isfinite(p.aspectRatio)) {
        ctx.fail(who + " has a non-finite znear/zfar/aspectRatio");
      }
    } else if (c.type == "orthographic") {
      const auto& o = c.orthographic;
      if (!(std::isfinite(o.ymag) && o.ymag != 0.0 && std::isfinite(o.xmag))) {
        ctx.fail(who + " has invalid xmag/ymag (must be finite and ymag non-zero)");
      }
      if (!std::isfinite(o.znear) || !std::isfinite(o.zfar)) {
        ctx.fail(who + " has a non-finite znear/zfar");
      }
    } else {
      ctx.fail(who + " has type \"" + c.type + "\" (must be perspective or orthographic)");
    }
  }
  for (size_t i = 0; i < m.lights.size(); ++i) {
    const tinygltf::Light& l = m.lights[i];
    const std::string who = "light " + str(i);
    if (l.type != "point" && l.type != "spot" && l.type != "directional") {
      ctx.fail(who + " has type \"" + l.type + "\" (must be point, spot or directional)");
    }
    if (!(l.color.empty() || l.color.size() == 3) || !finite_all(l.color) ||
        std::any_of(l.color.begin(), l.color.end(), [](double c) { return c < 0.0; })) {
      ctx.fail(who + " color must be 3 finite non-negative numbers");
    }
    if (!std::isfinite(l.intensity) || l.intensity < 0.0) {
      ctx.fail(who + " has intensity " + std::to_string(l.intensity) + " (must be >= 0)");
    }
    if (!std::isfinite(l.range) || l.range < 0.0) ctx.fail(who + " has an invalid range");
    if (l.type == "spot") {
      const double inner = l.spot.innerConeAngle, outer = l.spot.outerConeAngle;
      if (!(std::isfinite(inner) && std::isfinite(outer) && inner >= 0.0 && outer > 0.0 &&
            inner <= outer && outer <= std::numbers::pi / 2 + 1e-6)) {
        ctx.fail(who +
                 " has invalid cone angles (need 0 <= innerConeAngle <= outerConeAngle <= pi/2)");
      }
    }
  }
}

void validate_gpu_instancing(const Context& ctx, const tinygltf::Node& node,
                             const tinygltf::Value& ext, const std::string& who) {
  const Model& m = ctx.model;
  const std::string ewho = who + " EXT_mesh_gpu_instancing";
  if (!ext.IsObject() || !ext.Has("attributes") || !ext.Get("attributes").IsObject()) {
    ctx.fail(ewho + " has no \"attributes\" object");
  }
  if (node.mesh < 0) ctx.fail(ewho + " is on a node without a mesh");
  const tinygltf::Value& attrs = ext.Get("attributes");
  size_t count = 0;
  bool have = false;
  for (const std::string& name : attrs.Keys()) {
    const tinygltf::Value& v = attrs.Get(name);
    if (!v.IsInt()) ctx.fail(ewho + " attribute " + name + " is not an accessor index");
    const int index = v.Get<int>();
    check_ref(ctx, index, m.accessors.size(), false, ewho + " attribute " + name, "accessor");
    const tinygltf::Accessor& a = m.accessors[size_t(index)];
    const bool f = a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT && !a.normalized;
    if ((name == "TRANSLATION" || name == "SCALE") && !(a.type == TINYGLTF_TYPE_VEC3 && f)) {
      ctx.fail(ewho + " " + name + " must be VEC3 FLOAT, but is " + format_name(a));
    }
    if (name == "ROTATION" &&
        !(a.type == TINYGLTF_TYPE_VEC4 &&
          (f || (a.normalized && (a.componentType == TINYGLTF_COMPONENT_TYPE_BYTE ||
                                  a.componentType == TINYGLTF_COMPONENT_TYPE_SHORT))))) {
      ctx.fail(ewho + " ROTATION must be VEC4 FLOAT or normalized BYTE/SHORT, but is " +
               format_name(a));
    }
    if (have && a.count != count) ctx.fail(ewho + " attributes have different counts");
    count = a.count;
    have = true;
  }
}

void validate_nodes_and_scenes(const Context& ctx) {
  const Model& m = ctx.model;
  const size_t n = m.nodes.size();
  std::vector<int> parent(n, -1);
  for (size_t i = 0; i < n; ++i) {
    const tinygltf::Node& node = m.nodes[i];
    const std::string who = "node " + str(i);
    check_ref(ctx, node.mesh, m.meshes.size(), true, who, "mesh");
    check_ref(ctx, node.camera, m.cameras.size(), true, who, "camera");
    check_ref(ctx, node.skin, m.skins.size(), true, who, "skin");
    for (int c : node.children) {
      check_ref(ctx, c, n, false, who + " (children)", "node");
      if (size_t(c) == i) ctx.fail(who + " lists itself as a child (node hierarchy cycle)");
      if (parent[size_t(c)] == int(i)) ctx.fail(who + " lists child " + str(c) + " twice");
      if (parent[size_t(c)] != -1) {
        ctx.fail("node " + str(c) + " has more than one parent (nodes " + str(parent[size_t(c)]) +
                 " and " + str(i) + "); glTF node hierarchies must be trees");
      }
      parent[size_t(c)] = int(i);
    }
    const bool sizes_ok = (node.matrix.empty() || node.matrix.size() == 16) &&
                          (node.translation.empty() || node.translation.size() == 3) &&
                          (node.rotation.empty() || node.rotation.size() == 4) &&
                          (node.scale.empty() || node.scale.size() == 3);
    if (!sizes_ok) ctx.fail(who + " has a matrix/translation/rotation/scale of the wrong length");
    if (!finite_all(node.matrix) || !finite_all(node.translation) || !finite_all(node.rotation) ||
        !finite_all(node.scale)) {
      ctx.fail(who + " has a non-finite transform value");
    }
    if (node.rotation.size() == 4) {
      const double len2 = node.rotation[0] * node.rotation[0] +
                          node.rotation[1] * node.rotation[1] +
                          node.rotation[2] * node.rotation[2] + node.rotation[3] * node.rotation[3];
      if (!(len2 > 1e-12)) ctx.fail(who + " has a zero rotation quaternion");
    }
    for (const auto& [name, ext] : node.extensions) {
      if (name == "KHR_lights_punctual") {
        if (!ext.IsObject() || !ext.Has("light") || !ext.Get("light").IsInt()) {
          ctx.fail(who + " KHR_lights_punctual has no integer \"light\"");
        }
        check_ref(ctx, ext.Get("light").Get<int>(), m.lights.size(), false,
                  who + " KHR_lights_punctual", "light");
      } else if (name == "EXT_mesh_gpu_instancing") {
        validate_gpu_instancing(ctx, node, ext, who);
      }
    }
  }
  // With at most one parent per node, a cycle is a parent chain that comes
  // back to itself. Walk each chain once (state: 0 new, 1 on this walk, 2 done).
  std::vector<uint8_t> state(n, 0);
  std::vector<size_t> walk;
  for (size_t start = 0; start < n; ++start) {
    walk.clear();
    for (size_t cur = start; state[cur] != 2;) {
      if (state[cur] == 1) {
        // Back on this walk: walk[k..] is the loop, each entry the child of
        // the next. Print it parent -> child.
        const auto k = std::find(walk.begin(), walk.end(), cur);
        std::string text;
        for (auto it = walk.end(); it != k;)
          text += str(*--it) + " -> ";
        text += str(walk.back());
        ctx.fail("node hierarchy has a cycle (nodes " + text + ")");
      }
      state[cur] = 1;
      walk.push_back(cur);
      if (parent[cur] < 0) break;
      cur = size_t(parent[cur]);
    }
    for (size_t w : walk)
      state[w] = 2;
  }
  for (size_t s = 0; s < m.scenes.size(); ++s) {
    std::vector<bool> seen(n, false);
    for (int root : m.scenes[s].nodes) {
      const std::string who = "scene " + str(s);
      check_ref(ctx, root, n, false, who, "node");
      if (parent[size_t(root)] != -1) {
        ctx.fail(who + " lists node " + str(root) + ", which is a child of node " +
                 str(parent[size_t(root)]) + " (scene nodes must be roots)");
      }
      if (seen[size_t(root)]) ctx.fail(who + " lists node " + str(root) + " twice");
      seen[size_t(root)] = true;
    }
  }
  if (m.defaultScene != -1) {
    if (m.scenes.empty()) {
      ctx.fail("\"scene\" is " + str(m.defaultScene) + " but the file has no \"scenes\"");
    }
    check_ref(ctx, m.defaultScene, m.scenes.size(), false, "\"scene\"", "scene");
  }
  for (size_t i = 0; i < m.skins.size(); ++i) {
    const tinygltf::Skin& skin = m.skins[i];
    const std::string who = "skin " + str(i);
    check_ref(ctx, skin.inverseBindMatrices, m.accessors.size(), true, who, "accessor");
    check_ref(ctx, skin.skeleton, n, true, who + " skeleton", "node");
    for (int j : skin.joints)
      check_ref(ctx, j, n, false, who + " joint", "node");
    if (skin.joints.empty()) ctx.fail(who + " has no joints");
    // Palette slots are 16-bit, one kept for the mesh node itself.
    if (skin.joints.size() >= 65535) {
      ctx.fail(who + " has " + str(skin.joints.size()) + " joints (at most 65534 are supported)");
    }
    if (skin.inverseBindMatrices >= 0) {
      const tinygltf::Accessor& a = m.accessors[size_t(skin.inverseBindMatrices)];
      if (a.type != TINYGLTF_TYPE_MAT4 || a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT) {
        ctx.fail(who + " inverseBindMatrices must be MAT4 FLOAT, but is " + format_name(a));
      }
      if (a.count != skin.joints.size()) {
        ctx.fail(who + " has " + str(a.count) + " inverse bind matrices for " +
                 str(skin.joints.size()) + " joints (there must be one per joint)");
      }
    }
  }
  for (size_t i = 0; i < m.nodes.size(); ++i) {
    const tinygltf::Node& node = m.nodes[i];
    if (node.weights.empty() || node.mesh < 0) continue;
    const size_t targets = m.meshes[size_t(node.mesh)].primitives.front().targets.size();
    if (node.weights.size() != targets) {
      ctx.fail("node " + str(i) + " has " + str(node.weights.size()) + " weights but its mesh " +
               str(node.mesh) + " has " + str(targets) + " morph targets");
    }
    if (!finite_all(node.weights)) ctx.fail("node " + str(i) + " has a weight that is not finite");
  }
}

// Whether an "extensions" object of `value` or of anything inside it (the
// texture infos inside a KHR_materials_* block) names `ext`.
bool value_uses_extension(const tinygltf::Value& value, const std::string& ext) {
  if (value.IsArray()) {
    for (size_t i = 0; i < value.ArrayLen(); ++i)
      if (value_uses_extension(value.Get(int(i)), ext)) return true;
    return false;
  }
  if (!value.IsObject()) return false;
  if (value.Has("extensions") && value.Get("extensions").IsObject() &&
      value.Get("extensions").Has(ext))
    return true;
  for (const std::string& key : value.Keys())
    if (value_uses_extension(value.Get(key), ext)) return true;
  return false;
}

bool map_uses_extension(const tinygltf::ExtensionMap& extensions, const std::string& ext) {
  if (extensions.count(ext)) return true;
  for (const auto& [name, value] : extensions)
    if (value_uses_extension(value, ext)) return true;
  return false;
}

// Whether anything in the file carries data of extension `ext`: the
// "extensions" object of the file or of any of its objects.
bool file_uses_extension(const Model& m, const std::string& ext) {
  auto any = [&](const auto& objects) {
    return std::any_of(objects.begin(), objects.end(),
                       [&](const auto& o) { return map_uses_extension(o.extensions, ext); });
  };
  if (map_uses_extension(m.extensions, ext) || map_uses_extension(m.asset.extensions, ext))
    return true;
  if (any(m.scenes) || any(m.nodes) || any(m.meshes) || any(m.materials) || any(m.textures) ||
      any(m.images) || any(m.samplers) || any(m.accessors) || any(m.bufferViews) ||
      any(m.buffers) || any(m.animations) || any(m.skins) || any(m.cameras) || any(m.lights))
    return true;
  for (const tinygltf::Mesh& mesh : m.meshes)
    if (any(mesh.primitives)) return true;
  for (const tinygltf::Material& mat : m.materials) {
    const tinygltf::PbrMetallicRoughness& pbr = mat.pbrMetallicRoughness;
    for (const tinygltf::ExtensionMap* e :
         {&pbr.extensions, &pbr.baseColorTexture.extensions,
          &pbr.metallicRoughnessTexture.extensions, &mat.normalTexture.extensions,
          &mat.occlusionTexture.extensions, &mat.emissiveTexture.extensions})
      if (map_uses_extension(*e, ext)) return true;
  }
  return false;
}

void validate_asset_and_extensions(const Context& ctx) {
  const Model& m = ctx.model;
  const std::string& version = m.asset.version;
  if (version.rfind("2.", 0) != 0) {
    ctx.fail("asset.version is \"" + version + "\"; only glTF 2.x is supported");
  }
  if (!m.asset.minVersion.empty() && m.asset.minVersion != "2.0") {
    ctx.fail("asset.minVersion is \"" + m.asset.minVersion + "\"; only glTF 2.0 is supported");
  }
  for (const std::string& ext : m.extensionsRequired) {
    if (extension_supported(ext) || extension_ignorable(ext)) continue;
    // Exporters list extensions they did not end up using (MSFT_texture_dds
    // in a file without images): nothing to misread.
    if (!file_uses_extension(m, ext)) {
      ctx.warn("the file requires extension " + ext +
               ", which is not supported, but nothing in it uses it; loading it without");
      continue;
    }
    ctx.fail("the file requires extension " + ext + ", which is not supported");
  }
}

}  // namespace

bool extension_supported(const std::string& name) {
  static const char* const kSupported[] = {
      "KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_materials_transmission",
      "KHR_materials_ior",   "KHR_materials_specular",          "KHR_materials_clearcoat",
      "KHR_materials_sheen", "KHR_texture_transform",           "EXT_mesh_gpu_instancing",
  };
  return std::find(std::begin(kSupported), std::end(kSupported), name) != std::end(kSupported);
}

bool extension_ignorable(const std::string& name) {
  // Shading detail we do not model (the base material still looks right),
  // metadata, and animation-only data.
  static const char* const kIgnorable[] = {
      "KHR_materials_volume",
      "KHR_materials_iridescence",
      "KHR_materials_anisotropy",
      "KHR_materials_dispersion",
      "KHR_materials_variants",
      "KHR_materials_unlit",
      "KHR_materials_diffuse_transmission",
      "KHR_xmp",
      "KHR_xmp_json_ld",
      "KHR_animation_pointer",
  };
  return std::find(std::begin(kIgnorable), std::end(kIgnorable), name) != std::end(kIgnorable);
}

void validate_model(Context& ctx) {
  validate_asset_and_extensions(ctx);
  validate_buffer_views(ctx);
  validate_accessors(ctx);
  validate_textures(ctx);
  validate_materials(ctx);
  validate_meshes(ctx);
  validate_cameras_and_lights(ctx);
  validate_nodes_and_scenes(ctx);
}

}  // namespace tandem::gltf
