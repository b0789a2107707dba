// PLY reader/writer for the scene-bundle mesh (hand-written: small, fuzzed, no PCL here).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

#include "common/atomic_file.h"
#include "common/color.h"
#include "common/error.h"
#include "scene/mesh.h"

namespace lp {
namespace {

enum class Type { kInt8, kUInt8, kInt16, kUInt16, kInt32, kUInt32, kFloat32, kFloat64, kInvalid };

Type ParseType(const std::string& s) {
  if (s == "char" || s == "int8") return Type::kInt8;
  if (s == "uchar" || s == "uint8") return Type::kUInt8;
  if (s == "short" || s == "int16") return Type::kInt16;
  if (s == "ushort" || s == "uint16") return Type::kUInt16;
  if (s == "int" || s == "int32") return Type::kInt32;
  if (s == "uint" || s == "uint32") return Type::kUInt32;
  if (s == "float" || s == "float32") return Type::kFloat32;
  if (s == "double" || s == "float64") return Type::kFloat64;
  return Type::kInvalid;
}

int TypeSize(Type t) {
  switch (t) {
    case Type::kInt8: case Type::kUInt8: return 1;
    case Type::kInt16: case Type::kUInt16: return 2;
    case Type::kInt32: case Type::kUInt32: case Type::kFloat32: return 4;
    case Type::kFloat64: return 8;
    default: return 0;
  }
}

struct Property {
  std::string name;
  Type type = Type::kInvalid;
  bool is_list = false;
  Type count_type = Type::kInvalid;
};

struct Element {
  std::string name;
  std::size_t count = 0;
  std::vector<Property> props;
};

enum class Format { kAscii, kBinaryLE, kBinaryBE };

class Reader {
 public:
  Reader(const std::string& bytes, std::size_t pos, Format fmt, const std::string& name)
      : b_(bytes), pos_(pos), fmt_(fmt), name_(name) {}

  double Read(Type t) {
    if (fmt_ == Format::kAscii) return ReadAscii();
    const int n = TypeSize(t);
    if (pos_ + n > b_.size()) Fail("file is truncated");
    unsigned char buf[8];
    std::memcpy(buf, b_.data() + pos_, n);
    pos_ += n;
    if (fmt_ == Format::kBinaryBE) std::reverse(buf, buf + n);
    switch (t) {
      case Type::kInt8: { std::int8_t v; std::memcpy(&v, buf, 1); return v; }
      case Type::kUInt8: return buf[0];
      case Type::kInt16: { std::int16_t v; std::memcpy(&v, buf, 2); return v; }
      case Type::kUInt16: { std::uint16_t v; std::memcpy(&v, buf, 2); return v; }
      case Type::kInt32: { std::int32_t v; std::memcpy(&v, buf, 4); return v; }
      case Type::kUInt32: { std::uint32_t v; std::memcpy(&v, buf, 4); return v; }
      case Type::kFloat32: { float v; std::memcpy(&v, buf, 4); return v; }
      case Type::kFloat64: { double v; std::memcpy(&v, buf, 8); return v; }
      default: Fail("invalid property type");
    }
  }
  [[noreturn]] void Fail(const std::string& what) const { throw InputError(name_, what); }
  std::size_t remaining() const { return b_.size() - pos_; }

 private:
  double ReadAscii() {
    while (pos_ < b_.size() && std::isspace(static_cast<unsigned char>(b_[pos_]))) ++pos_;
    if (pos_ >= b_.size()) Fail("file is truncated");
    std::size_t end = pos_;
    while (end < b_.size() && !std::isspace(static_cast<unsigned char>(b_[end]))) ++end;
    const std::string tok = b_.substr(pos_, std::min<std::size_t>(end - pos_, 64));
    pos_ = end;
    char* stop = nullptr;
    const double v = std::strtod(tok.c_str(), &stop);
    if (stop == tok.c_str() || *stop != '\0') Fail("bad number '" + tok + "'");
    return v;
  }

  const std::string& b_;
  std::size_t pos_;
  Format fmt_;
  std::string name_;
};

struct Header {
  Format format = Format::kAscii;
  std::vector<Element> elements;
  std::size_t data_start = 0;  ///< the first byte after end_header's line
};

/// One `property` line (after the keyword) of the element being declared.
Property ParseProperty(std::istringstream& ls, const std::string& line, const std::string& name) {
  Property p;
  std::string t;
  ls >> t;
  if (t == "list") {
    std::string ct, it;
    ls >> ct >> it >> p.name;
    p.is_list = true;
    p.count_type = ParseType(ct);
    p.type = ParseType(it);
    if (p.count_type == Type::kInvalid || p.type == Type::kInvalid || p.count_type == Type::kFloat32 ||
        p.count_type == Type::kFloat64)
      throw InputError(name, "bad list property '" + line + "'");
  } else {
    p.type = ParseType(t);
    ls >> p.name;
    if (p.type == Type::kInvalid) throw InputError(name, "unknown property type '" + t + "'");
  }
  return p;
}

Header ParseHeader(const std::string& bytes, const std::string& name) {
  auto fail = [&](const std::string& what) { throw InputError(name, what); };
  if (bytes.compare(0, 4, "ply\n") != 0 && bytes.compare(0, 5, "ply\r\n") != 0)
    fail("not a PLY file (missing 'ply' magic)");
  const std::size_t header_end = bytes.find("end_header");
  if (header_end == std::string::npos) fail("PLY header has no end_header");
  Header h;
  h.data_start = bytes.find('\n', header_end);
  if (h.data_start == std::string::npos) fail("PLY header is not terminated by a newline");
  ++h.data_start;

  std::istringstream header(bytes.substr(0, header_end));
  std::string line;
  std::getline(header, line);
  bool have_format = false;
  while (std::getline(header, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string kw;
    ls >> kw;
    if (kw.empty() || kw == "comment" || kw == "obj_info") continue;
    if (kw == "format") {
      std::string f;
      ls >> f;
      if (f == "ascii") h.format = Format::kAscii;
      else if (f == "binary_little_endian") h.format = Format::kBinaryLE;
      else if (f == "binary_big_endian") h.format = Format::kBinaryBE;
      else fail("unknown PLY format '" + f + "'");
      have_format = true;
    } else if (kw == "element") {
      Element e;
      long long count = -1;
      ls >> e.name >> count;
      if (!ls || count < 0) fail("bad element line '" + line + "'");
      e.count = static_cast<std::size_t>(count);
      h.elements.push_back(e);
    } else if (kw == "property") {
      if (h.elements.empty()) fail("property before any element");
      h.elements.back().props.push_back(ParseProperty(ls, line, name));
    } else {
      fail("unknown header keyword '" + kw + "'");
    }
  }
  if (!have_format) fail("PLY header has no format line");
  return h;
}

/// Which property holds each value the mesh takes (-1: none).
struct VertexLayout {
  int x = -1, y = -1, z = -1, nx = -1, ny = -1, nz = -1, r = -1, g = -1, b = -1;
  int sr = -1, sg = -1, sb = -1;  ///< shaded_red ...: the colour seen, linear float
  int label = -1, er = -1, eg = -1, eb = -1;  ///< emitter, radiance_r ...: emitters.ply's
  int face = -1;                  ///< a face element's vertex index list

  explicit VertexLayout(const Element& e) {
    const bool is_face = e.name == "face";
    for (int i = 0; i < static_cast<int>(e.props.size()); ++i) {
      const std::string& n = e.props[i].name;
      if (e.props[i].is_list) {
        if (is_face && (n == "vertex_indices" || n == "vertex_index")) face = i;
        continue;
      }
      if (n == "x") x = i; else if (n == "y") y = i; else if (n == "z") z = i;
      else if (n == "nx") nx = i; else if (n == "ny") ny = i; else if (n == "nz") nz = i;
      else if (n == "red" || n == "r" || n == "diffuse_red") r = i;
      else if (n == "green" || n == "g" || n == "diffuse_green") g = i;
      else if (n == "blue" || n == "b" || n == "diffuse_blue") b = i;
      else if (n == "shaded_red") sr = i; else if (n == "shaded_green") sg = i; else if (n == "shaded_blue") sb = i;
      else if (n == "emitter") label = i;
      else if (n == "radiance_r") er = i; else if (n == "radiance_g") eg = i; else if (n == "radiance_b") eb = i;
    }
  }
};

void ReadVertices(const Element& e, Reader& r, Mesh* mesh) {
  const VertexLayout l(e);
  if (l.x < 0 || l.y < 0 || l.z < 0) r.Fail("vertex element lacks x, y, z");
  const bool has_n = l.nx >= 0 && l.ny >= 0 && l.nz >= 0;
  const bool has_c = l.r >= 0 && l.g >= 0 && l.b >= 0;
  const bool has_s = l.sr >= 0 && l.sg >= 0 && l.sb >= 0;
  const bool has_e = l.er >= 0 && l.eg >= 0 && l.eb >= 0;
  if (has_s) mesh->shaded.reserve(e.count);
  mesh->positions.reserve(e.count);
  if (has_n) mesh->normals.reserve(e.count);
  mesh->albedo.reserve(e.count);
  std::vector<double> vals(e.props.size());
  for (std::size_t k = 0; k < e.count; ++k) {
    for (std::size_t i = 0; i < e.props.size(); ++i) {
      const Property& p = e.props[i];
      if (p.is_list) {
        const double n = r.Read(p.count_type);
        if (n < 0 || n > 1e6) r.Fail("bad list length in vertex element");
        for (int j = 0; j < static_cast<int>(n); ++j) r.Read(p.type);
        vals[i] = 0;
      } else {
        vals[i] = r.Read(p.type);
      }
    }
    mesh->positions.emplace_back(vals[l.x], vals[l.y], vals[l.z]);
    if (has_n) mesh->normals.emplace_back(vals[l.nx], vals[l.ny], vals[l.nz]);
    if (has_s) mesh->shaded.emplace_back(vals[l.sr], vals[l.sg], vals[l.sb]);
    if (l.label >= 0) {
      const double v = vals[l.label];
      if (!(v >= -1 && v <= 1e6) || v != std::floor(v)) r.Fail("an emitter id must be a whole number from -1");
      mesh->label.push_back(static_cast<int>(v));
    }
    if (has_e) mesh->emission.emplace_back(vals[l.er], vals[l.eg], vals[l.eb]);
    if (!has_c) {
      mesh->albedo.emplace_back(0.5f, 0.5f, 0.5f);
      continue;
    }
    // uchar colours are 0..255 sRGB; float colours are taken as sRGB in [0, 1].
    const double scale = TypeSize(e.props[l.r].type) == 1 ? 255.0 : 1.0;
    Eigen::Vector3f a;
    for (int c = 0; c < 3; ++c) {
      const double v = vals[c == 0 ? l.r : c == 1 ? l.g : l.b] / scale;
      a[c] = SrgbToLinear(static_cast<float>(std::clamp(std::isfinite(v) ? v : 0.0, 0.0, 1.0)));
    }
    mesh->albedo.push_back(a);
  }
}

/// Faces as triangle fans.
void ReadFaces(const Element& e, Reader& r, Mesh* mesh) {
  const int iface = VertexLayout(e).face;
  if (iface < 0) r.Fail("face element lacks vertex_indices");
  for (std::size_t k = 0; k < e.count; ++k) {
    for (std::size_t i = 0; i < e.props.size(); ++i) {
      const Property& p = e.props[i];
      if (!p.is_list) {
        r.Read(p.type);
        continue;
      }
      const double n = r.Read(p.count_type);
      if (!(n >= 0 && n <= 1024)) r.Fail("bad face vertex count");
      std::vector<int> idx(static_cast<int>(n));
      for (int j = 0; j < static_cast<int>(n); ++j) {
        const double v = r.Read(p.type);
        if (!(v >= 0 && v < 2147483647.0)) r.Fail("bad vertex index in face " + std::to_string(k));
        idx[j] = static_cast<int>(v);
      }
      if (static_cast<int>(i) != iface) continue;
      for (int j = 1; j + 1 < static_cast<int>(n); ++j) mesh->triangles.emplace_back(idx[0], idx[j], idx[j + 1]);
    }
  }
}

void SkipElement(const Element& e, Reader& r) {
  if (e.props.empty()) return;  // rows of no properties take no bytes, however many
  for (std::size_t k = 0; k < e.count; ++k)
    for (const Property& p : e.props) {
      if (p.is_list) {
        const double n = r.Read(p.count_type);
        if (!(n >= 0 && n <= 1e6)) r.Fail("bad list length in element '" + e.name + "'");
        for (int j = 0; j < static_cast<int>(n); ++j) r.Read(p.type);
      } else {
        r.Read(p.type);
      }
    }
}

}  // namespace

Mesh ParsePly(const std::string& bytes, const std::string& name) {
  const Header h = ParseHeader(bytes, name);
  Mesh mesh;
  Reader r(bytes, h.data_start, h.format, name);
  bool have_vertices = false, have_faces = false;
  for (const Element& e : h.elements) {
    // Every item takes at least one byte (binary) or two (ASCII): reject absurd counts early.
    std::size_t min_item = 0;
    for (const Property& p : e.props) min_item += p.is_list ? TypeSize(p.count_type) : TypeSize(p.type);
    if (h.format == Format::kAscii) min_item = 2 * e.props.size();
    if (min_item > 0 && e.count > r.remaining() / min_item) r.Fail("element '" + e.name + "' count exceeds file size");
    if (e.name == "vertex") {
      ReadVertices(e, r, &mesh);
      have_vertices = true;
    } else if (e.name == "face") {
      ReadFaces(e, r, &mesh);
      have_faces = true;
    } else {
      SkipElement(e, r);
    }
  }
  if (!have_vertices) r.Fail("PLY has no vertex element");
  if (!have_faces) r.Fail("PLY has no face element (a triangle mesh is required)");
  for (const auto& t : mesh.triangles)
    for (int c = 0; c < 3; ++c)
      if (t[c] >= static_cast<int>(mesh.positions.size()))
        r.Fail("face refers to vertex " + std::to_string(t[c]) + " but there are only " +
               std::to_string(mesh.positions.size()));
  return mesh;
}

Mesh ReadPly(const std::filesystem::path& path) { return ParsePly(ReadTextFile(path), path.string()); }

void WritePly(const std::filesystem::path& path, const Mesh& mesh) {
  LP_CHECK(mesh.normals.empty() || mesh.normals.size() == mesh.positions.size(), "normals size");
  LP_CHECK(mesh.albedo.size() == mesh.positions.size(), "albedo size");
  std::ostringstream os;
  os << "ply\nformat binary_little_endian 1.0\ncomment lightprobe mesh (colours sRGB-encoded)\n"
     << "element vertex " << mesh.positions.size() << "\n"
     << "property float x\nproperty float y\nproperty float z\n";
  if (!mesh.normals.empty()) os << "property float nx\nproperty float ny\nproperty float nz\n";
  LP_CHECK(mesh.shaded.empty() || mesh.shaded.size() == mesh.positions.size(), "shaded size");
  os << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  if (!mesh.shaded.empty()) os << "property float shaded_red\nproperty float shaded_green\nproperty float shaded_blue\n";
  LP_CHECK(mesh.label.empty() || mesh.label.size() == mesh.positions.size(), "label size");
  LP_CHECK(mesh.emission.empty() || mesh.emission.size() == mesh.positions.size(), "emission size");
  if (!mesh.label.empty()) os << "property int emitter\n";
  if (!mesh.emission.empty()) os << "property float radiance_r\nproperty float radiance_g\nproperty float radiance_b\n";
  os
     << "element face " << mesh.triangles.size() << "\nproperty list uchar int vertex_indices\nend_header\n";
  std::string data = os.str();
  auto put = [&](const void* p, std::size_t n) { data.append(static_cast<const char*>(p), n); };
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    put(mesh.positions[i].data(), 12);
    if (!mesh.normals.empty()) put(mesh.normals[i].data(), 12);
    for (int c = 0; c < 3; ++c) {
      const auto u = static_cast<unsigned char>(std::lround(255.f * LinearToSrgb(mesh.albedo[i][c])));
      put(&u, 1);
    }
    if (!mesh.shaded.empty()) put(mesh.shaded[i].data(), 12);
    if (!mesh.label.empty()) put(&mesh.label[i], 4);
    if (!mesh.emission.empty()) put(mesh.emission[i].data(), 12);
  }
  for (const auto& t : mesh.triangles) {
    const unsigned char three = 3;
    put(&three, 1);
    put(t.data(), 12);
  }
  WriteTextAtomically(path, data);
}

}  // namespace lp
