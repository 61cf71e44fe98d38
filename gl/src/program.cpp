#include "vdrig/gl/program.hpp"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/gl.h>
#include <GL/glext.h>

namespace vdrig::gl {
namespace {

// The shader's name, or 0 with the driver's log in *log.
GLuint compile(GLenum type, const std::string& source, std::string* log) {
  const GLuint shader = glCreateShader(type);
  const char* text = source.c_str();
  glShaderSource(shader, 1, &text, nullptr);
  glCompileShader(shader);
  GLint ok = 0;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (ok) return shader;
  char buf[4096] = {};
  glGetShaderInfoLog(shader, sizeof buf, nullptr, buf);
  *log = buf;
  glDeleteShader(shader);
  return 0;
}

}  // namespace

Result<unsigned> link_program(const std::string& vertex_source, const std::string& fragment_source,
                              const std::string& what) {
  std::string log;
  const GLuint vs = compile(GL_VERTEX_SHADER, vertex_source, &log);
  if (!vs) return make_error(ErrorCode::kInternal, what + ": vertex shader compilation failed: " + log);
  const GLuint fs = compile(GL_FRAGMENT_SHADER, fragment_source, &log);
  if (!fs) {
    glDeleteShader(vs);
    return make_error(ErrorCode::kInternal, what + ": fragment shader compilation failed: " + log);
  }
  const GLuint program = glCreateProgram();
  glAttachShader(program, vs);
  glAttachShader(program, fs);
  glLinkProgram(program);
  glDeleteShader(vs);  // flagged; freed with the program
  glDeleteShader(fs);
  GLint ok = 0;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (ok) return static_cast<unsigned>(program);
  char buf[4096] = {};
  glGetProgramInfoLog(program, sizeof buf, nullptr, buf);
  glDeleteProgram(program);
  return make_error(ErrorCode::kInternal, what + ": link failed: " + buf);
}

}  // namespace vdrig::gl
