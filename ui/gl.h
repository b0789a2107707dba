#pragma once
/// The little OpenGL 3.3 core the viewer needs: programs, textures, a mesh with
/// per-vertex colours, coloured lines, and reading the back buffer. Include only from
/// ui/ .cpp files (it pulls in GL and GLFW).
#define GL_GLEXT_PROTOTYPES 1
#define GLFW_INCLUDE_GLCOREARB 1
#include <GLFW/glfw3.h>

#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/image.h"
#include "scene/mesh.h"

namespace lp::ui {

/// A compiled and linked program; throws std::runtime_error with the GL log on failure.
class Program {
 public:
  Program(const char* vertex_source, const char* fragment_source);
  ~Program();
  Program(const Program&) = delete;
  Program& operator=(const Program&) = delete;
  void Use() const;
  int Uniform(const char* name) const;

 private:
  unsigned id_ = 0;
};

/// An RGB8 texture (linear filtering); Upload replaces the contents (any size).
class Texture {
 public:
  Texture();
  ~Texture();
  Texture(const Texture&) = delete;
  Texture& operator=(const Texture&) = delete;
  void Upload(int width, int height, const std::uint8_t* rgb);
  void Upload(const ImageRgb8& image) { Upload(image.width, image.height, image.data.data()); }
  unsigned id() const { return id_; }
  int width() const { return width_; }
  int height() const { return height_; }

 private:
  unsigned id_ = 0;
  int width_ = 0, height_ = 0;
};

/// Triangles with positions, normals and a per-vertex colour that can be replaced alone
/// (the shading modes). Draw with the mesh program.
class GlMesh {
 public:
  GlMesh();
  ~GlMesh();
  GlMesh(const GlMesh&) = delete;
  GlMesh& operator=(const GlMesh&) = delete;
  void SetGeometry(const Mesh& mesh);
  void SetColors(const std::vector<Eigen::Vector3f>& colors);  ///< one per vertex
  void Draw() const;
  std::size_t triangles() const { return index_count_ / 3; }
  std::size_t vertices() const { return vertex_count_; }

 private:
  unsigned vao_ = 0, positions_ = 0, normals_ = 0, colors_ = 0, indices_ = 0;
  std::size_t index_count_ = 0, vertex_count_ = 0;
};

/// Coloured line segments, rebuilt each frame.
class GlLines {
 public:
  GlLines();
  ~GlLines();
  GlLines(const GlLines&) = delete;
  GlLines& operator=(const GlLines&) = delete;
  void Clear() { data_.clear(); }
  void Add(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& color);
  void Draw();

 private:
  unsigned vao_ = 0, vbo_ = 0;
  std::vector<float> data_;  // x y z r g b per point
};

/// An offscreen colour + depth target (the 3D view is drawn into it only when it changes,
/// then shown as an image every frame).
class RenderTarget {
 public:
  RenderTarget();
  ~RenderTarget();
  RenderTarget(const RenderTarget&) = delete;
  RenderTarget& operator=(const RenderTarget&) = delete;
  /// Binds it for drawing at this size (reallocated when the size changes).
  void Bind(int width, int height);
  static void Unbind();
  unsigned texture() const { return color_; }

 private:
  unsigned fbo_ = 0, color_ = 0, depth_ = 0;
  int width_ = 0, height_ = 0;
};

/// The mesh program: mode 0 = vertex colour (already display-ready, sRGB-encoded in the
/// shader from linear), 1 = normals; optional headlight.
Program MeshProgram();
Program LineProgram();

/// Reads the current framebuffer (GL_BACK) as top-to-bottom RGB8.
ImageRgb8 ReadBackBuffer(int width, int height);

}  // namespace lp::ui
