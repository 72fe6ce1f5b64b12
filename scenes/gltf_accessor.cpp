// Accessor decoding. Only called on accessors that validate_model() has
// checked, so byte ranges are known to be inside their buffers; what is
// checked here is the data itself (finite floats, sparse indices).
#include <algorithm>
#include <cmath>
#include <cstring>

#include "scenes/gltf_internal.h"

namespace tandem::gltf {

namespace {

template <class T>
T load(const unsigned char* p) {
  T v;
  std::memcpy(&v, p, sizeof v);  // buffer data need not be aligned for T
  return v;
}

// glTF's normalized-integer decoding (spec section 3.11).
float component_to_float(const unsigned char* p, int ct, bool normalized) {
  switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return load<float>(p);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return normalized ? p[0] / 255.0f : float(p[0]);
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      const float v = float(load<int8_t>(p));
      return normalized ? std::max(v / 127.0f, -1.0f) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      const float v = float(load<uint16_t>(p));
      return normalized ? v / 65535.0f : v;
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      const float v = float(load<int16_t>(p));
      return normalized ? std::max(v / 32767.0f, -1.0f) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
      return float(load<uint32_t>(p));
    default:
      return 0.0f;
  }
}

uint32_t component_to_uint(const unsigned char* p, int ct) {
  switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return p[0];
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return load<uint16_t>(p);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
      return load<uint32_t>(p);
    default:
      return 0;
  }
}

// Byte offset of each component inside one element (matrix columns with
// 1- or 2-byte components are padded to 4 bytes).
std::vector<size_t> component_offsets(const tinygltf::Accessor& a) {
  const size_t cs = component_size(a.componentType);
  const int n = component_count(a.type);
  std::vector<size_t> offsets(static_cast<size_t>(n));
  const bool padded_matrix = a.type == TINYGLTF_TYPE_MAT2 || a.type == TINYGLTF_TYPE_MAT3;
  const size_t rows = a.type == TINYGLTF_TYPE_MAT2 ? 2 : 3;
  const size_t column = (rows * cs + 3) / 4 * 4;
  for (int k = 0; k < n; ++k) {
    offsets[size_t(k)] =
        padded_matrix ? (size_t(k) / rows) * column + (size_t(k) % rows) * cs : size_t(k) * cs;
  }
  return offsets;
}

const unsigned char* view_data(const tinygltf::Model& m, int view, size_t offset) {
  const tinygltf::BufferView& v = m.bufferViews[size_t(view)];
  return m.buffers[size_t(v.buffer)].data.data() + v.byteOffset + offset;
}

// Reads `count` elements of accessor `a`'s format from `base`, `stride`
// bytes apart, into out[0 .. count * components).
void read_elements(const tinygltf::Accessor& a, const unsigned char* base, size_t stride,
                   size_t count, float* out) {
  const int n = component_count(a.type);
  if (a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT && stride == size_t(n) * 4) {
    std::memcpy(out, base, count * size_t(n) * 4);  // the common, tightly packed case
    return;
  }
  const std::vector<size_t> offsets = component_offsets(a);
  for (size_t i = 0; i < count; ++i) {
    const unsigned char* e = base + i * stride;
    for (int k = 0; k < n; ++k) {
      out[i * size_t(n) + size_t(k)] =
          component_to_float(e + offsets[size_t(k)], a.componentType, a.normalized);
    }
  }
}

size_t dense_stride(const tinygltf::Model& m, const tinygltf::Accessor& a) {
  const size_t stride = m.bufferViews[size_t(a.bufferView)].byteStride;
  return stride != 0 ? stride : accessor_element_size(a.componentType, a.type);
}

// Sparse indices, checked to be in range and strictly increasing (the spec
// requires both; out-of-range ones would write past the dense array).
std::vector<uint32_t> sparse_indices(const Context& ctx, const tinygltf::Accessor& a,
                                     const std::string& who) {
  const auto& s = a.sparse;
  const int ct = s.indices.componentType;
  const size_t cs = component_size(ct);
  const unsigned char* base =
      view_data(ctx.model, s.indices.bufferView, size_t(s.indices.byteOffset));
  std::vector<uint32_t> indices(size_t(s.count));
  for (size_t j = 0; j < indices.size(); ++j) {
    indices[j] = component_to_uint(base + j * cs, ct);
    if (indices[j] >= a.count) {
      ctx.fail(who + ": sparse index " + std::to_string(indices[j]) + " is out of range (count " +
               std::to_string(a.count) + ")");
    }
    if (j > 0 && indices[j] <= indices[j - 1]) {
      ctx.fail(who + ": sparse indices are not strictly increasing");
    }
  }
  return indices;
}

}  // namespace

size_t component_size(int ct) {
  switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return 4;
    default:
      return 0;  // INT and DOUBLE are not glTF 2.0 accessor types
  }
}

int component_count(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return 1;
    case TINYGLTF_TYPE_VEC2:
      return 2;
    case TINYGLTF_TYPE_VEC3:
      return 3;
    case TINYGLTF_TYPE_VEC4:
      return 4;
    case TINYGLTF_TYPE_MAT2:
      return 4;
    case TINYGLTF_TYPE_MAT3:
      return 9;
    case TINYGLTF_TYPE_MAT4:
      return 16;
    default:
      return 0;
  }
}

size_t accessor_element_size(int component_type, int type) {
  const size_t cs = component_size(component_type);
  const int n = component_count(type);
  if (cs == 0 || n == 0) return 0;
  // Matrix columns start on 4-byte boundaries.
  if (type == TINYGLTF_TYPE_MAT2 || type == TINYGLTF_TYPE_MAT3) {
    const size_t rows = type == TINYGLTF_TYPE_MAT2 ? 2 : 3;
    const size_t column = (rows * cs + 3) / 4 * 4;
    return column * rows;
  }
  return cs * size_t(n);
}

void AccessorCache::charge(const tinygltf::Accessor& a, size_t bytes_per_element,
                           const std::string& who) {
  // Elements of an accessor without a bufferView cost no file bytes at all,
  // so they are counted separately (and more strictly) as well.
  if (a.bufferView < 0) {
    ctx_.charge(Budget::kZeroFilledElements, a.count,
                who + " (" + std::to_string(a.count) + " elements without a bufferView)");
  }
  // Sparse indices and values are decoded into temporaries alongside.
  const uint64_t sparse =
      a.sparse.isSparse ? uint64_t(a.sparse.count) * (4 + bytes_per_element) : 0;
  ctx_.charge(Budget::kAccessorBytes, uint64_t(a.count) * bytes_per_element + sparse,
              who + " (" + std::to_string(a.count) + " elements)");
}

const std::vector<float>& AccessorCache::floats(int index, const std::string& what) {
  if (auto it = floats_.find(index); it != floats_.end()) return it->second;
  const tinygltf::Model& m = ctx_.model;
  const tinygltf::Accessor& a = m.accessors[size_t(index)];
  const std::string who = what + " (accessor " + std::to_string(index) + ")";
  const size_t n = size_t(component_count(a.type));
  charge(a, n * sizeof(float), who);
  std::vector<float> out(a.count * n, 0.0f);  // no bufferView: zeros
  if (a.bufferView >= 0) {
    read_elements(a, view_data(m, a.bufferView, a.byteOffset), dense_stride(m, a), a.count,
                  out.data());
  }
  if (a.sparse.isSparse) {
    const std::vector<uint32_t> indices = sparse_indices(ctx_, a, who);
    std::vector<float> values(indices.size() * n);
    const size_t esize = accessor_element_size(a.componentType, a.type);
    read_elements(a, view_data(m, a.sparse.values.bufferView, size_t(a.sparse.values.byteOffset)),
                  esize, indices.size(), values.data());
    for (size_t j = 0; j < indices.size(); ++j) {
      std::memcpy(&out[indices[j] * n], &values[j * n], n * sizeof(float));
    }
  }
  if (a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT) {
    for (size_t i = 0; i < out.size(); ++i) {
      if (!std::isfinite(out[i])) {
        ctx_.fail(who + " has a non-finite value (" + std::to_string(out[i]) + ") in element " +
                  std::to_string(i / n));
      }
    }
  }
  return floats_.emplace(index, std::move(out)).first->second;
}

const std::vector<uint32_t>& AccessorCache::uints(int index, const std::string& what) {
  if (auto it = uints_.find(index); it != uints_.end()) return it->second;
  const tinygltf::Model& m = ctx_.model;
  const tinygltf::Accessor& a = m.accessors[size_t(index)];
  const std::string who = what + " (accessor " + std::to_string(index) + ")";
  charge(a, sizeof(uint32_t), who);
  std::vector<uint32_t> out(a.count, 0u);
  const int ct = a.componentType;
  if (a.bufferView >= 0) {
    const unsigned char* base = view_data(m, a.bufferView, a.byteOffset);
    const size_t stride = dense_stride(m, a);
    if (ct == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT && stride == 4) {
      std::memcpy(out.data(), base, out.size() * 4);
    } else {
      for (size_t i = 0; i < out.size(); ++i)
        out[i] = component_to_uint(base + i * stride, ct);
    }
  }
  if (a.sparse.isSparse) {
    const std::vector<uint32_t> indices = sparse_indices(ctx_, a, who);
    const size_t cs = component_size(ct);
    const unsigned char* values =
        view_data(m, a.sparse.values.bufferView, size_t(a.sparse.values.byteOffset));
    for (size_t j = 0; j < indices.size(); ++j)
      out[indices[j]] = component_to_uint(values + j * cs, ct);
  }
  return uints_.emplace(index, std::move(out)).first->second;
}

}  // namespace tandem::gltf
