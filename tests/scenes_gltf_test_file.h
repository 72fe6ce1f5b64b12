// Small glTF files written in a test: one embedded buffer (a base64 data:
// URI) with one bufferView per array and accessors on those views. Shared
// by the loader's hand-written-file tests and the skinning/morph tests, so
// the files they build follow one set of rules.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace tandem::test {

// RFC 4648 base64 with padding.
inline std::string base64(const std::vector<unsigned char>& data) {
  static const char* digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < data.size(); i += 3) {
    const uint32_t n = uint32_t(data[i]) << 16 |
                       (i + 1 < data.size() ? uint32_t(data[i + 1]) << 8 : 0) |
                       (i + 2 < data.size() ? uint32_t(data[i + 2]) : 0);
    out += digits[(n >> 18) & 63];
    out += digits[(n >> 12) & 63];
    out += i + 1 < data.size() ? digits[(n >> 6) & 63] : '=';
    out += i + 2 < data.size() ? digits[n & 63] : '=';
  }
  return out;
}

class GltfTestFile {
 public:
  // Adds a bufferView holding `values` (4-byte aligned, as accessors of
  // 4-byte components need); returns its index.
  template <class T>
  int view(const std::vector<T>& values, int stride = 0) {
    while (bytes_.size() % 4 != 0)
      bytes_.push_back(0);
    const size_t offset = bytes_.size();
    const auto* p = reinterpret_cast<const unsigned char*>(values.data());
    bytes_.insert(bytes_.end(), p, p + values.size() * sizeof(T));
    views_.push_back(R"({"buffer": 0, "byteOffset": )" + std::to_string(offset) +
                     R"(, "byteLength": )" + std::to_string(values.size() * sizeof(T)) +
                     (stride ? R"(, "byteStride": )" + std::to_string(stride) : "") + "}");
    return int(views_.size() - 1);
  }
  // Adds an accessor given as JSON; returns its index.
  int accessor(const std::string& json) {
    accessors_.push_back(json);
    return int(accessors_.size() - 1);
  }
  // An accessor of `count` elements of `type` ("VEC3", ...) and glTF
  // component type (5121 u8, 5123 u16, 5126 float, ...) on a view of its own.
  template <class T>
  int add(const std::vector<T>& values, int component_type, const char* type, size_t count,
          bool normalized = false) {
    return accessor(R"({"bufferView": )" + std::to_string(view(values)) + R"(, "componentType": )" +
                    std::to_string(component_type) + R"(, "type": ")" + type + R"(", "count": )" +
                    std::to_string(count) + (normalized ? R"(, "normalized": true)" : "") + "}");
  }
  // A float VEC3 accessor on its own view.
  int vec3(const std::vector<float>& values) {
    return add(values, 5126, "VEC3", values.size() / 3);
  }
  // A complete file: asset, the data, and `members` (JSON object members
  // without the surrounding braces: meshes, nodes, scenes, ...).
  std::string file(const std::string& members) const {
    auto list = [](const std::vector<std::string>& items) {
      std::string out;
      for (const std::string& i : items)
        out += (out.empty() ? "" : ", ") + i;
      return "[" + out + "]";
    };
    return R"({"asset": {"version": "2.0"}, "buffers": [{"byteLength": )" +
           std::to_string(bytes_.size()) + R"(, "uri": "data:application/octet-stream;base64,)" +
           base64(bytes_) + R"("}], "bufferViews": )" + list(views_) + R"(, "accessors": )" +
           list(accessors_) + (members.empty() ? "" : ", " + members) + "}";
  }

 private:
  std::vector<unsigned char> bytes_;
  std::vector<std::string> views_, accessors_;
};

// One triangle in the z = 0 plane, as a flat VEC3 array.
inline const std::vector<float> kTriangle = {0, 0, 0, 1, 0, 0, 0, 1, 0};

}  // namespace tandem::test
