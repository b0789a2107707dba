#include "common/image_io.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <cstdint>
#include <mutex>
#include <optional>
#include <sstream>
#include <streambuf>
#include <string_view>
#include <utility>

#include <unistd.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/atomic_file.h"
#include "common/color.h"
#include "common/error.h"

namespace lp {
namespace fs = std::filesystem;
namespace {

// OpenCV reads these once, at first use of the codec registry: OpenEXR on, and a cap
// on the pixels a header may claim (64 Mpx: a corrupt header must not allocate GiBs).
const bool kExrEnabled = [] {
  ::setenv("OPENCV_IO_ENABLE_OPENEXR", "1", 0);
  ::setenv("OPENCV_IO_MAX_IMAGE_PIXELS", "67108864", 0);
  return true;
}();

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

/// OpenCV prints a line to std::cerr for a file it cannot decode ("imread_(...): can't
/// read header: ..."); our error says it once. While any decode runs, std::cerr writes go
/// nowhere (a count, so overlapping decodes on several threads restore it once). Nothing
/// of ours writes to std::cerr (messages go through stdio), so nothing else is lost.
class QuietCerr {
 public:
  QuietCerr() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (depth_++ == 0) saved_ = std::cerr.rdbuf(&null_);
  }
  ~QuietCerr() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (--depth_ == 0) std::cerr.rdbuf(saved_);
  }
  QuietCerr(const QuietCerr&) = delete;
  QuietCerr& operator=(const QuietCerr&) = delete;

 private:
  struct NullBuf : std::streambuf {
    int overflow(int c) override { return traits_type::not_eof(c); }
  };
  static inline std::mutex mutex_;
  static inline int depth_ = 0;
  static inline std::streambuf* saved_ = nullptr;
  static inline NullBuf null_;
};

/// OpenEXR's magic number (the file's first 4 bytes).
const char kExrMagic[] = "\x76\x2f\x31\x01";

/// One attribute of an OpenEXR header: its name, where its value starts in the header and
/// its declared size.
struct ExrAttribute {
  std::string_view name;
  std::size_t value = 0;
  std::uint32_t size = 0;
};

/// Calls `f` for each attribute of the OpenEXR header at the start of `h` (name, type,
/// u32 size, value; a 0 byte ends them) while it returns true, stopping where `h` ends.
template <class F>
void ForEachExrAttribute(const std::string& h, F&& f) {
  if (h.size() < 8 || h.compare(0, 4, kExrMagic) != 0) return;
  std::size_t i = 8;
  while (i < h.size() && h[i] != '\0') {
    const std::size_t name_end = h.find('\0', i);
    const std::size_t type_end = name_end == std::string::npos ? name_end : h.find('\0', name_end + 1);
    if (type_end == std::string::npos || type_end + 5 > h.size()) return;
    ExrAttribute a{std::string_view(h).substr(i, name_end - i), type_end + 5, 0};
    for (int k = 3; k >= 0; --k) a.size = (a.size << 8) | std::uint8_t(h[type_end + 1 + k]);
    if (!f(a)) return;
    i = a.value + a.size;
  }
}

/// Width and height as a header claims them, for the formats the project reads (PNG,
/// OpenEXR, PFM, PGM/PPM, Radiance HDR), from the file's first bytes; nothing for other
/// formats (OpenCV's own cap, 2^30 pixels, then applies) or a header too short to say.
std::optional<std::pair<std::uint64_t, std::uint64_t>> HeaderSize(const std::string& h) {
  auto u32be = [&](std::size_t i) {
    return (std::uint64_t(std::uint8_t(h[i])) << 24) | (std::uint64_t(std::uint8_t(h[i + 1])) << 16) |
           (std::uint64_t(std::uint8_t(h[i + 2])) << 8) | std::uint64_t(std::uint8_t(h[i + 3]));
  };
  auto i32le = [&](std::size_t i) {
    std::uint32_t v = 0;
    for (int k = 3; k >= 0; --k) v = (v << 8) | std::uint8_t(h[i + k]);
    return static_cast<std::int64_t>(static_cast<std::int32_t>(v));
  };
  if (h.size() >= 24 && h.compare(0, 8, "\x89PNG\r\n\x1a\n") == 0 && h.compare(12, 4, "IHDR") == 0)
    return std::make_pair(u32be(16), u32be(20));
  if (h.compare(0, 4, kExrMagic) == 0) {  // OpenEXR: the dataWindow attribute (box2i, inclusive)
    std::optional<std::pair<std::uint64_t, std::uint64_t>> size;
    ForEachExrAttribute(h, [&](const ExrAttribute& a) {
      if (a.name != "dataWindow" || a.size != 16) return true;
      if (a.value + 16 > h.size()) return false;
      const std::int64_t x0 = i32le(a.value), y0 = i32le(a.value + 4), x1 = i32le(a.value + 8), y1 = i32le(a.value + 12);
      if (x1 >= x0 && y1 >= y0) size = std::make_pair(std::uint64_t(x1 - x0 + 1), std::uint64_t(y1 - y0 + 1));
      return false;  // (an empty window: the decoder refuses it)
    });
    return size;
  }
  auto two_numbers = [&](std::size_t from) -> std::optional<std::pair<std::uint64_t, std::uint64_t>> {
    std::uint64_t v[2];
    std::size_t i = from;
    for (int k = 0; k < 2; ++k) {
      while (i < h.size() && (std::isspace(std::uint8_t(h[i])) || h[i] == '#')) {
        if (h[i] == '#') i = h.find('\n', i) == std::string::npos ? h.size() : h.find('\n', i);
        else ++i;
      }
      if (i >= h.size() || !std::isdigit(std::uint8_t(h[i]))) return std::nullopt;
      v[k] = 0;
      for (; i < h.size() && std::isdigit(std::uint8_t(h[i])); ++i) v[k] = std::min<std::uint64_t>(v[k] * 10 + (h[i] - '0'), 1ull << 40);
    }
    return std::make_pair(v[0], v[1]);
  };
  if (h.size() >= 3 && h[0] == 'P' && (h[1] == 'F' || h[1] == 'f' || (h[1] >= '1' && h[1] <= '6')) &&
      std::isspace(std::uint8_t(h[2])))
    return two_numbers(2);  // PFM, PGM, PPM: "P? width height"
  if (h.compare(0, 2, "#?") == 0) {  // Radiance: header lines, a blank line, then e.g. "-Y h +X w"
    const std::size_t blank = h.find("\n\n");
    if (blank == std::string::npos) return std::nullopt;
    std::istringstream line(h.substr(blank + 2, 128));
    std::string axis1, axis2;
    std::uint64_t n1 = 0, n2 = 0;
    if (!(line >> axis1 >> n1 >> axis2 >> n2) || axis1.size() != 2 || axis2.size() != 2) return std::nullopt;
    return axis1[1] == 'Y' ? std::make_pair(n2, n1) : std::make_pair(n1, n2);
  }
  return std::nullopt;
}

/// The most pixels `bytes` of a file whose header starts `head` can hold: uncompressed
/// formats (PFM, binary PGM/PPM) at least their samples' bytes; Radiance HDR at least 2
/// bytes per run of 127 in each of 4 components; the rest (PNG, OpenEXR: deflate, at most
/// 1032:1) a 1-bit pixel at deflate's best. A header claiming more is corrupt (or a
/// decompression bomb): no decoder allocates for it.
std::uint64_t MostPixelsFor(const std::string& head, std::uint64_t bytes) {
  if (head.size() >= 2 && head[0] == 'P') {
    switch (head[1]) {
      case 'F': return bytes / 12;  // 3 floats
      case 'f': return bytes / 4;
      case '5': return bytes;       // 1 byte a sample at least
      case '6': return bytes / 3;
      case '4': return bytes * 8;
      default: return bytes / 2;    // text: a digit and a space a sample at least
    }
  }
  if (head.compare(0, 2, "#?") == 0) return bytes * 127 / 8;
  return bytes * 8 * 1032;
}

/// OpenEXR allocates each header attribute's declared size before reading it (and keeps
/// attributes it does not know whole): an attribute claiming more bytes than the file has
/// is corrupt, refused before OpenEXR allocates up to 2 GiB for it.
void CheckExrAttributes(const std::string& h, std::uint64_t bytes, const std::string& name) {
  ForEachExrAttribute(h, [&](const ExrAttribute& a) {
    if (a.value + std::uint64_t(a.size) > bytes)
      throw InputError(name, "corrupt OpenEXR header: attribute '" + std::string(a.name.substr(0, 32)) + "' claims " +
                                 std::to_string(a.size) + " bytes, more than the file's " + std::to_string(bytes));
    return true;
  });
}

/// Refuses a file whose header claims more than kMaxImagePixels, or more than its bytes
/// can hold, before any decoder allocates for it.
void CheckClaimedSize(const fs::path& path, const std::string& name) {
  std::ifstream in(path, std::ios::binary);
  std::string head(64 * 1024, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  std::error_code ec;
  const std::uint64_t bytes = fs::file_size(path, ec);
  if (ec) return;  // the decoder says why
  CheckExrAttributes(head, bytes, name);
  const auto size = HeaderSize(head);
  if (!size) return;
  const std::uint64_t pixels = size->first * size->second;
  const std::string claims = "header claims " + std::to_string(size->first) + " x " + std::to_string(size->second) + " pixels";
  if (pixels > kMaxImagePixels)
    throw InputError(name, claims + ", more than the " + std::to_string(kMaxImagePixels) + " an image may have");
  if (pixels > MostPixelsFor(head, bytes))
    throw InputError(name, claims + ", more than its " + std::to_string(bytes) + " bytes can hold");
}

cv::Mat Checked(cv::Mat m, const std::string& name) {
  if (m.empty()) throw InputError(name, "cannot decode image (unsupported or corrupt)");
  if (m.dims != 2 || m.rows <= 0 || m.cols <= 0) throw InputError(name, "image has no pixels");
  return m;
}

/// From a file itself: cv::imdecode would copy EXR and PFM bytes into a temporary file of
/// its own, which OpenCV leaves in /tmp when the decoder refuses them.
cv::Mat ReadRaw(const fs::path& path, int flags, const std::string& name) {
  (void)kExrEnabled;
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(name, "file not found");
  if (fs::is_directory(path, ec)) throw InputError(name, "is a directory, expected an image");
  if (fs::file_size(path, ec) == 0 && !ec) throw InputError(name, "empty file, expected an image");
  CheckClaimedSize(path, name);
  cv::Mat m;
  try {
    QuietCerr quiet;
    m = cv::imread(path.string(), flags);
  } catch (const cv::Exception& e) {
    throw InputError(name, std::string("cannot decode image: ") + e.what());
  }
  return Checked(std::move(m), name);
}
cv::Mat ReadRaw(const fs::path& path, int flags) { return ReadRaw(path, flags, path.string()); }

/// Bytes in memory: through a temporary file of ours, removed whatever happens.
cv::Mat DecodeRaw(const std::string& bytes, const std::string& name, int flags) {
  if (bytes.empty()) throw InputError(name, "empty file, expected an image");
  std::error_code ec;
  const fs::path tmp_dir = fs::temp_directory_path(ec);
  if (ec) throw InputError(name, "no temporary directory to decode it in: " + ec.message());
  std::string tmpl = (tmp_dir / "lightprobe-decode-XXXXXX").string();
  const int fd = ::mkstemp(tmpl.data());
  if (fd < 0) throw InputError(name, "cannot create a temporary file to decode it");
  ::close(fd);
  struct Remove {
    std::string path;
    ~Remove() {
      std::error_code ec;
      fs::remove(path, ec);
    }
  } remove{tmpl};
  {
    std::ofstream out(tmpl, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out) throw InputError(name, "cannot write a temporary file to decode it");
  }
  return ReadRaw(tmpl, flags, name);
}

ImageRGB FromMat(const cv::Mat& m, const fs::path& path, ImageEncoding* enc_out) {
  const int ch = m.channels();
  if (ch != 1 && ch != 3 && ch != 4)
    throw InputError(path.string(), "unsupported channel count " + std::to_string(ch));
  ImageRGB img(m.cols, m.rows);
  ImageEncoding enc;
  switch (m.depth()) {
    case CV_8U: enc = ImageEncoding::kSrgb8; break;
    case CV_16U: enc = ImageEncoding::kLinear16; break;
    case CV_32F: case CV_16F: enc = ImageEncoding::kLinearFloat; break;
    default: throw InputError(path.string(), "unsupported pixel type");
  }
  cv::Mat f;
  m.convertTo(f, CV_MAKETYPE(CV_32F, ch));
  for (int y = 0; y < m.rows; ++y) {
    const float* row = f.ptr<float>(y);
    for (int x = 0; x < m.cols; ++x) {
      float bgr[3];
      if (ch == 1) {
        bgr[0] = bgr[1] = bgr[2] = row[x];
      } else {
        for (int c = 0; c < 3; ++c) bgr[c] = row[x * ch + c];
      }
      float* out = img.at(x, y);
      for (int c = 0; c < 3; ++c) {
        float v = bgr[2 - c];
        if (enc == ImageEncoding::kSrgb8) v = SrgbToLinear(v / 255.f);
        else if (enc == ImageEncoding::kLinear16) v = v / 65535.f;
        out[c] = v;
      }
    }
  }
  if (enc_out) *enc_out = enc;
  return img;
}

cv::Mat ToMat(const ImageRGB& image) {
  cv::Mat m(image.height, image.width, CV_32FC3);
  for (int y = 0; y < image.height; ++y) {
    float* row = m.ptr<float>(y);
    for (int x = 0; x < image.width; ++x) {
      const float* p = image.at(x, y);
      row[3 * x + 0] = p[2];
      row[3 * x + 1] = p[1];
      row[3 * x + 2] = p[0];
    }
  }
  return m;
}

void WriteMat(const fs::path& path, const cv::Mat& m) {
  WriteAtomically(path, [&](const fs::path& tmp) {
    bool ok = false;
    errno = 0;
    try {
      ok = cv::imwrite(tmp.string(), m);
    } catch (const cv::Exception& e) {
      const std::string why = WriteFailure(tmp.parent_path(), errno);
      throw InputError(path.string(), "cannot write image: " + (why.empty() ? std::string(e.what()) : why));
    }
    if (!ok) {
      const std::string why = WriteFailure(tmp.parent_path(), errno);
      throw InputError(path.string(), why.empty() ? "cannot write image" : "cannot write image: " + why);
    }
  });
}

}  // namespace

const char* ToString(ImageEncoding e) {
  switch (e) {
    case ImageEncoding::kLinearFloat: return "linear float";
    case ImageEncoding::kSrgb8: return "8-bit sRGB-encoded (decoded to linear)";
    case ImageEncoding::kLinear16: return "16-bit linear";
  }
  return "?";
}

ImageRGB ReadImageLinear(const fs::path& path, ImageEncoding* encoding) {
  const std::string ext = Lower(path.extension().string());
  if (ext != ".exr" && ext != ".pfm" && ext != ".png" && ext != ".hdr" && ext != ".jpg" && ext != ".jpeg")
    throw InputError(path.string(), "unsupported image format '" + ext + "' (use .exr, .pfm, .png or .jpg)");
  return FromMat(ReadRaw(path, cv::IMREAD_UNCHANGED), path, encoding);
}

ImageRGB DecodeImageLinear(const std::string& bytes, const std::string& name, ImageEncoding* encoding) {
  return FromMat(DecodeRaw(bytes, name, cv::IMREAD_UNCHANGED), name, encoding);
}

namespace {

Mask MaskFromMat(const cv::Mat& m, const std::string& name) {
  if (m.depth() != CV_8U) throw InputError(name, "mask must be an 8-bit PNG");
  Mask mask;
  mask.width = m.cols;
  mask.height = m.rows;
  mask.data.resize(static_cast<std::size_t>(m.cols) * m.rows);
  const int ch = m.channels();
  for (int y = 0; y < m.rows; ++y)
    for (int x = 0; x < m.cols; ++x)
      mask.data[static_cast<std::size_t>(y) * m.cols + x] = m.ptr<unsigned char>(y)[x * ch];
  return mask;
}

}  // namespace

Mask ReadMask(const fs::path& path) { return MaskFromMat(ReadRaw(path, cv::IMREAD_UNCHANGED), path.string()); }

Mask DecodeMask(const std::string& bytes, const std::string& name) {
  return MaskFromMat(DecodeRaw(bytes, name, cv::IMREAD_UNCHANGED), name);
}

ImageRGB ReadHdr(const fs::path& path) {
  if (Lower(path.extension().string()) != ".hdr")
    throw InputError(path.string(), "expected a Radiance .hdr file");
  return FromMat(ReadRaw(path, cv::IMREAD_UNCHANGED), path, nullptr);
}

void WriteExr(const fs::path& path, const ImageRGB& image) { WriteMat(path, ToMat(image)); }

void WriteHdr(const fs::path& path, const ImageRGB& image) { WriteMat(path, ToMat(image)); }

ImageRgb8 EncodeSrgb8(const ImageRGB& image, float exposure) {
  ImageRgb8 out{image.width, image.height, std::vector<std::uint8_t>(image.data.size())};
  for (std::size_t i = 0; i < image.data.size(); ++i) {
    float v = image.data[i] * exposure;
    if (!std::isfinite(v)) v = 0.f;
    out.data[i] = static_cast<std::uint8_t>(std::lround(255.f * LinearToSrgb(v)));
  }
  return out;
}

void WritePngSrgb(const fs::path& path, const ImageRGB& image, float exposure) {
  WriteRgb8Png(path, EncodeSrgb8(image, exposure));
}

void WritePng8(const fs::path& path, int width, int height, const std::vector<unsigned char>& rgb) {
  LP_CHECK(rgb.size() == static_cast<std::size_t>(3) * width * height, "size mismatch");
  cv::Mat m(height, width, CV_8UC3);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      for (int c = 0; c < 3; ++c)
        m.ptr<unsigned char>(y)[3 * x + (2 - c)] = rgb[3 * (static_cast<std::size_t>(y) * width + x) + c];
  WriteMat(path, m);
}

ImageRgb8 ReadRgb8(const fs::path& path) {
  const cv::Mat m = ReadRaw(path, cv::IMREAD_UNCHANGED);
  if (m.depth() != CV_8U) throw InputError(path.string(), "expected an 8-bit colour image");
  cv::Mat rgb;
  switch (m.channels()) {
    case 1: cv::cvtColor(m, rgb, cv::COLOR_GRAY2RGB); break;
    case 3: cv::cvtColor(m, rgb, cv::COLOR_BGR2RGB); break;
    case 4: cv::cvtColor(m, rgb, cv::COLOR_BGRA2RGB); break;
    default: throw InputError(path.string(), "unsupported channel count " + std::to_string(m.channels()));
  }
  ImageRgb8 out;
  out.width = rgb.cols;
  out.height = rgb.rows;
  out.data.resize(out.pixels() * 3);
  for (int y = 0; y < rgb.rows; ++y)
    std::copy_n(rgb.ptr<std::uint8_t>(y), 3 * rgb.cols, &out.data[3 * static_cast<std::size_t>(y) * rgb.cols]);
  return out;
}

DepthImage ReadDepth16(const fs::path& path, double to_millimetres) {
  const cv::Mat m = ReadRaw(path, cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR);
  if (m.depth() != CV_16U || m.channels() != 1)
    throw InputError(path.string(), "expected a 16-bit single-channel depth image");
  DepthImage out;
  out.width = m.cols;
  out.height = m.rows;
  out.data.resize(out.pixels());
  for (int y = 0; y < m.rows; ++y) {
    const std::uint16_t* row = m.ptr<std::uint16_t>(y);
    for (int x = 0; x < m.cols; ++x) {
      const double mm = std::round(row[x] * to_millimetres);
      out.data[static_cast<std::size_t>(y) * m.cols + x] = mm > 0 && mm <= 65535 ? static_cast<std::uint16_t>(mm) : 0;
    }
  }
  return out;
}

void WriteRgb8Png(const fs::path& path, const ImageRgb8& image) {
  LP_CHECK(image.data.size() == image.pixels() * 3, "size mismatch");
  cv::Mat rgb(image.height, image.width, CV_8UC3, const_cast<std::uint8_t*>(image.data.data())), bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  WriteMat(path, bgr);
}

void WriteDepth16Png(const fs::path& path, const DepthImage& image) {
  LP_CHECK(image.data.size() == image.pixels(), "size mismatch");
  cv::Mat m(image.height, image.width, CV_16UC1, const_cast<std::uint16_t*>(image.data.data()));
  WriteMat(path, m.clone());
}

void WriteMask(const fs::path& path, const Mask& mask) {
  cv::Mat m(mask.height, mask.width, CV_8UC1, const_cast<std::uint8_t*>(mask.data.data()));
  WriteMat(path, m.clone());
}

void Viridis(float t, float rgb[3]) {
  // Piecewise-linear approximation of matplotlib's viridis.
  static const float kStops[5][3] = {{0.267f, 0.005f, 0.329f}, {0.229f, 0.322f, 0.546f},
                                     {0.128f, 0.567f, 0.551f}, {0.369f, 0.789f, 0.383f},
                                     {0.993f, 0.906f, 0.144f}};
  const float x = std::clamp(std::isfinite(t) ? t : 0.f, 0.f, 1.f) * 4.f;
  const int k = std::min(3, static_cast<int>(x));
  const float f = x - k;
  for (int c = 0; c < 3; ++c) rgb[c] = kStops[k][c] * (1 - f) + kStops[k + 1][c] * f;
}

ImageRgb8 Heatmap(int width, int height, const std::vector<float>& values, float max_value) {
  ImageRgb8 out{width, height, std::vector<std::uint8_t>(static_cast<std::size_t>(3) * width * height, 0)};
  for (std::size_t i = 0; i < values.size() && i < out.pixels(); ++i) {
    const float v = values[i];
    if (!std::isfinite(v) || v < 0.f) continue;  // invalid / masked: black
    float c[3];
    Viridis(max_value > 0.f ? v / max_value : 0.f, c);
    for (int k = 0; k < 3; ++k) out.data[3 * i + k] = static_cast<std::uint8_t>(std::lround(255.f * c[k]));
  }
  return out;
}

void WriteHeatmapPng(const fs::path& path, int width, int height, const std::vector<float>& values,
                     float max_value) {
  WriteRgb8Png(path, Heatmap(width, height, values, max_value));
}

}  // namespace lp
