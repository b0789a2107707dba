#pragma once
/// Image files (OpenCV stays inside image_io.cpp). Every reader throws
/// InputError naming the file and the problem; writers are atomic.
#include <cstdint>
#include <filesystem>
#include <string>

#include "common/image.h"

namespace lp {

/// The most pixels an image file may claim (64 Mpx), checked from its header before it is
/// decoded (PNG, OpenEXR, PFM, PGM/PPM, Radiance HDR; OpenCV's own 2^30 for the rest):
/// a corrupt header must not make a decoder allocate gigabytes.
inline constexpr std::uint64_t kMaxImagePixels = 64ull << 20;

/// How ReadImageLinear interpreted the file.
enum class ImageEncoding { kLinearFloat, kSrgb8, kLinear16 };
const char* ToString(ImageEncoding e);

/// Reads .exr / .pfm / .hdr (linear float), 8-bit PNG or JPEG (sRGB-encoded, decoded to linear)
/// or 16-bit PNG (linear, /65535). Grey images are expanded to RGB.
ImageRGB ReadImageLinear(const std::filesystem::path& path, ImageEncoding* encoding = nullptr);

/// Reads an 8-bit single-channel mask PNG (a colour PNG uses its first channel).
Mask ReadMask(const std::filesystem::path& path);
/// The same from the file's bytes (what the readers do after reading it); `name` is
/// used in errors. The format is recognized from the content.
ImageRGB DecodeImageLinear(const std::string& bytes, const std::string& name, ImageEncoding* encoding = nullptr);
Mask DecodeMask(const std::string& bytes, const std::string& name);

/// Reads an 8-bit colour image (PNG, JPEG, PPM; grey is expanded, alpha dropped) as it is
/// stored: sRGB-encoded RGB. Throws InputError for other depths.
ImageRgb8 ReadRgb8(const std::filesystem::path& path);
/// Reads a 16-bit single-channel depth image (PNG or PGM) and multiplies each value by
/// `to_millimetres` (1 for millimetre files, 0.2 for TUM's 5000-per-metre files),
/// rounding; values that do not fit in uint16 become 0 (invalid).
DepthImage ReadDepth16(const std::filesystem::path& path, double to_millimetres = 1.0);
/// Writers for the same (PNG, atomically).
void WriteRgb8Png(const std::filesystem::path& path, const ImageRgb8& image);
void WriteDepth16Png(const std::filesystem::path& path, const DepthImage& image);

/// Reads a Radiance .hdr (RGBE) environment map as linear RGB.
ImageRGB ReadHdr(const std::filesystem::path& path);

/// 32-bit float OpenEXR, linear.
void WriteExr(const std::filesystem::path& path, const ImageRGB& image);
/// Radiance .hdr (RGBE, run-length encoded), linear; top row first. `path` ends in .hdr.
void WriteHdr(const std::filesystem::path& path, const ImageRGB& image);
/// Linear RGB to what an 8-bit camera stores: times `exposure`, clipped to [0, 1],
/// sRGB-encoded (non-finite values become 0).
ImageRgb8 EncodeSrgb8(const ImageRGB& image, float exposure = 1.f);
/// 8-bit PNG, sRGB-encoded after multiplying by `exposure` (values clamped).
void WritePngSrgb(const std::filesystem::path& path, const ImageRGB& image, float exposure = 1.f);
/// 8-bit PNG with an explicit colour per pixel (already encoded, 0..255 RGB).
void WritePng8(const std::filesystem::path& path, int width, int height,
               const std::vector<unsigned char>& rgb);
/// 8-bit single-channel mask PNG.
void WriteMask(const std::filesystem::path& path, const Mask& mask);

/// The error colour map used everywhere (error_view*.png, the viewer's error shading and
/// keyframe error): a piecewise-linear viridis, t in [0, 1] (clamped) -> linear 0..1 RGB
/// as displayed (sRGB-encoded values).
void Viridis(float t, float rgb[3]);

/// Maps a non-negative scalar image to the colour map (Viridis), `max_value` at the top of
/// the scale; negative or non-finite values (masked) are black.
ImageRgb8 Heatmap(int width, int height, const std::vector<float>& values, float max_value);

/// Heatmap() written as a PNG.
void WriteHeatmapPng(const std::filesystem::path& path, int width, int height,
                     const std::vector<float>& values, float max_value);

}  // namespace lp
