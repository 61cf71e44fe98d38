// Compiling and linking GLSL programs: the one place for the driver's error log, used by the viewer's renderers and
// by probe_gl's fusion shader.
#pragma once

#include <string>

#include "vdrig/core/result.hpp"

namespace vdrig::gl {

/// The vertex stage of a full-screen pass (GLSL 3.30 core), for link_program: one triangle with corners (-1, -1),
/// (3, -1) and (-1, 3) in clip space, taken from gl_VertexID, which covers the viewport [-1, 1]^2 exactly once (no
/// seam between two triangles). Draw it with glDrawArrays(GL_TRIANGLES, 0, 3) and an empty vertex array object bound
/// (no attributes); it passes nothing on, so the fragment stage works from gl_FragCoord and its uniforms.
inline constexpr const char* kFullScreenTriangleVertexShader = R"(#version 330 core
void main() {
  vec2 p = vec2((gl_VertexID == 1) ? 3.0 : -1.0, (gl_VertexID == 2) ? 3.0 : -1.0);
  gl_Position = vec4(p, 0.0, 1.0);
}
)";

/// Compiles both stages and links them into a program; returns its GL name (a GLuint). Needs a current OpenGL
/// context (gl::Context, context.hpp). A stage that does not compile, or a program that does not link, is kInternal
/// with `what`
/// ("fusion shader") and the driver's log; nothing stays allocated then. The caller deletes the program.
Result<unsigned> link_program(const std::string& vertex_source, const std::string& fragment_source,
                              const std::string& what);

}  // namespace vdrig::gl
