#include "ui/gl.h"

#include <stdexcept>

namespace lp::ui {

namespace {

unsigned Compile(GLenum type, const char* source) {
  const unsigned s = glCreateShader(type);
  glShaderSource(s, 1, &source, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048];
    glGetShaderInfoLog(s, sizeof log, nullptr, log);
    glDeleteShader(s);
    throw std::runtime_error(std::string("GL shader: ") + log);
  }
  return s;
}

}  // namespace

Program::Program(const char* vertex_source, const char* fragment_source) {
  const unsigned vs = Compile(GL_VERTEX_SHADER, vertex_source), fs = Compile(GL_FRAGMENT_SHADER, fragment_source);
  id_ = glCreateProgram();
  glAttachShader(id_, vs);
  glAttachShader(id_, fs);
  glLinkProgram(id_);
  glDeleteShader(vs);
  glDeleteShader(fs);
  GLint ok = 0;
  glGetProgramiv(id_, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048];
    glGetProgramInfoLog(id_, sizeof log, nullptr, log);
    throw std::runtime_error(std::string("GL program: ") + log);
  }
}

Program::~Program() { glDeleteProgram(id_); }
void Program::Use() const { glUseProgram(id_); }
int Program::Uniform(const char* name) const { return glGetUniformLocation(id_, name); }

Texture::Texture() { glGenTextures(1, &id_); }
Texture::~Texture() { glDeleteTextures(1, &id_); }

void Texture::Upload(int width, int height, const std::uint8_t* rgb) {
  glBindTexture(GL_TEXTURE_2D, id_);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB8, width, height, 0, GL_RGB, GL_UNSIGNED_BYTE, rgb);
  width_ = width;
  height_ = height;
}

GlMesh::GlMesh() {
  glGenVertexArrays(1, &vao_);
  glGenBuffers(1, &positions_);
  glGenBuffers(1, &normals_);
  glGenBuffers(1, &colors_);
  glGenBuffers(1, &indices_);
}

GlMesh::~GlMesh() {
  const unsigned buffers[] = {positions_, normals_, colors_, indices_};
  glDeleteBuffers(4, buffers);
  glDeleteVertexArrays(1, &vao_);
}

void GlMesh::SetGeometry(const Mesh& mesh) {
  glBindVertexArray(vao_);
  auto attribute = [](unsigned buffer, int location, const std::vector<Eigen::Vector3f>& data) {
    glBindBuffer(GL_ARRAY_BUFFER, buffer);
    glBufferData(GL_ARRAY_BUFFER, data.size() * sizeof(Eigen::Vector3f), data.data(), GL_STATIC_DRAW);
    glEnableVertexAttribArray(location);
    glVertexAttribPointer(location, 3, GL_FLOAT, GL_FALSE, sizeof(Eigen::Vector3f), nullptr);
  };
  attribute(positions_, 0, mesh.positions);
  std::vector<Eigen::Vector3f> normals = mesh.normals;
  normals.resize(mesh.positions.size(), Eigen::Vector3f::UnitZ());
  attribute(normals_, 1, normals);
  std::vector<Eigen::Vector3f> colors = mesh.albedo;
  colors.resize(mesh.positions.size(), Eigen::Vector3f::Constant(0.5f));
  glBindBuffer(GL_ARRAY_BUFFER, colors_);
  glBufferData(GL_ARRAY_BUFFER, colors.size() * sizeof(Eigen::Vector3f), colors.data(), GL_DYNAMIC_DRAW);
  glEnableVertexAttribArray(2);
  glVertexAttribPointer(2, 3, GL_FLOAT, GL_FALSE, sizeof(Eigen::Vector3f), nullptr);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, indices_);
  glBufferData(GL_ELEMENT_ARRAY_BUFFER, mesh.triangles.size() * sizeof(Eigen::Vector3i), mesh.triangles.data(),
               GL_STATIC_DRAW);
  glBindVertexArray(0);
  index_count_ = mesh.triangles.size() * 3;
  vertex_count_ = mesh.positions.size();
}

void GlMesh::SetColors(const std::vector<Eigen::Vector3f>& colors) {
  if (colors.size() != vertex_count_) return;
  glBindBuffer(GL_ARRAY_BUFFER, colors_);
  glBufferSubData(GL_ARRAY_BUFFER, 0, colors.size() * sizeof(Eigen::Vector3f), colors.data());
}

void GlMesh::Draw() const {
  if (index_count_ == 0) return;
  glBindVertexArray(vao_);
  glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(index_count_), GL_UNSIGNED_INT, nullptr);
  glBindVertexArray(0);
}

GlLines::GlLines() {
  glGenVertexArrays(1, &vao_);
  glGenBuffers(1, &vbo_);
}

GlLines::~GlLines() {
  glDeleteBuffers(1, &vbo_);
  glDeleteVertexArrays(1, &vao_);
}

void GlLines::Add(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& color) {
  data_.insert(data_.end(), {a.x(), a.y(), a.z(), color.x(), color.y(), color.z()});
  data_.insert(data_.end(), {b.x(), b.y(), b.z(), color.x(), color.y(), color.z()});
}

void GlLines::Draw() {
  if (data_.empty()) return;
  glBindVertexArray(vao_);
  glBindBuffer(GL_ARRAY_BUFFER, vbo_);
  glBufferData(GL_ARRAY_BUFFER, data_.size() * sizeof(float), data_.data(), GL_STREAM_DRAW);
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), nullptr);
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), reinterpret_cast<void*>(3 * sizeof(float)));
  glDrawArrays(GL_LINES, 0, static_cast<GLsizei>(data_.size() / 6));
  glBindVertexArray(0);
}

RenderTarget::RenderTarget() {
  glGenFramebuffers(1, &fbo_);
  glGenTextures(1, &color_);
  glGenRenderbuffers(1, &depth_);
}

RenderTarget::~RenderTarget() {
  glDeleteRenderbuffers(1, &depth_);
  glDeleteTextures(1, &color_);
  glDeleteFramebuffers(1, &fbo_);
}

void RenderTarget::Bind(int width, int height) {
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
  if (width != width_ || height != height_) {
    glBindTexture(GL_TEXTURE_2D, color_);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, width, height, 0, GL_RGBA, GL_UNSIGNED_BYTE, nullptr);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, color_, 0);
    glBindRenderbuffer(GL_RENDERBUFFER, depth_);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, width, height);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw std::runtime_error("GL: the offscreen framebuffer is incomplete");
    width_ = width;
    height_ = height;
  }
  glViewport(0, 0, width, height);
}

void RenderTarget::Unbind() { glBindFramebuffer(GL_FRAMEBUFFER, 0); }

Program MeshProgram() {
  return Program(R"(#version 330 core
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
layout(location = 2) in vec3 color;
uniform mat4 view_projection;
out vec3 v_normal;
out vec3 v_color;
out vec3 v_position;
void main() {
  v_normal = normal;
  v_color = color;
  v_position = position;
  gl_Position = view_projection * vec4(position, 1.0);
})",
                 R"(#version 330 core
in vec3 v_normal;
in vec3 v_color;
in vec3 v_position;
uniform int mode;          // 0 = colour (linear, encoded to sRGB here), 1 = normals
uniform int headlight;     // shade by the angle to the eye
uniform float exposure;
uniform vec3 eye;
out vec4 frag;
void main() {
  vec3 n = normalize(v_normal);
  if (mode == 1) { frag = vec4(0.5 * n + 0.5, 1.0); return; }
  vec3 c = v_color * exposure;
  if (headlight == 1) c *= 0.35 + 0.65 * abs(dot(n, normalize(eye - v_position)));
  c = clamp(c, 0.0, 1.0);
  vec3 srgb = mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, c));
  frag = vec4(srgb, 1.0);
})");
}

Program LineProgram() {
  return Program(R"(#version 330 core
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 color;
uniform mat4 view_projection;
out vec3 v_color;
void main() { v_color = color; gl_Position = view_projection * vec4(position, 1.0); })",
                 R"(#version 330 core
in vec3 v_color;
out vec4 frag;
void main() { frag = vec4(v_color, 1.0); })");
}

ImageRgb8 ReadBackBuffer(int width, int height) {
  ImageRgb8 out;
  out.width = width;
  out.height = height;
  out.data.resize(static_cast<std::size_t>(width) * height * 3);
  std::vector<std::uint8_t> rows(out.data.size());
  glReadBuffer(GL_BACK);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, width, height, GL_RGB, GL_UNSIGNED_BYTE, rows.data());
  const std::size_t stride = static_cast<std::size_t>(width) * 3;
  for (int y = 0; y < height; ++y)
    std::copy(rows.begin() + (height - 1 - y) * stride, rows.begin() + (height - y) * stride,
              out.data.begin() + y * stride);
  return out;
}

}  // namespace lp::ui
