// link_program: a working pair links into a program; a stage that does not compile, or a pair that does not link,
// is kInternal naming the program and the failing step with the driver's log.
#define GL_GLEXT_PROTOTYPES 1
#include "vdrig/gl/program.hpp"

#include <GL/gl.h>
#include <GL/glext.h>
#include <gtest/gtest.h>

#include "vdrig/gl/context.hpp"
#include "vdrig/test/require_gl.hpp"

namespace vdrig::gl {
namespace {

const char* kVertex = R"(#version 330 core
out vec2 v_uv;
void main() { v_uv = vec2(0.0); gl_Position = vec4(0.0, 0.0, 0.0, 1.0); }
)";
const char* kFragment = R"(#version 330 core
in vec2 v_uv;
out vec4 out_colour;
void main() { out_colour = vec4(v_uv, 0.0, 1.0); }
)";

TEST(GlProgram, LinksAGoodPairAndNamesTheFailingStageOtherwise) {
  auto ctx = Context::create(16, 16, false);
  if (!ctx) VDRIG_SKIP_WITHOUT_GL() << "no OpenGL display: " << ctx.error().message;

  auto good = link_program(kVertex, kFragment, "test shader");
  ASSERT_TRUE(good) << good.error().describe();
  EXPECT_EQ(glIsProgram(good.value()), GL_TRUE);
  glDeleteProgram(good.value());

  auto bad_fragment = link_program(kVertex, "#version 330 core\nvoid main() { undeclared = 1.0; }\n", "test shader");
  ASSERT_FALSE(bad_fragment);
  EXPECT_EQ(bad_fragment.error().code, ErrorCode::kInternal);
  EXPECT_NE(bad_fragment.error().message.find("test shader: fragment shader compilation failed"), std::string::npos)
      << bad_fragment.error().message;
  EXPECT_NE(bad_fragment.error().message.find("undeclared"), std::string::npos) << "the driver's log";

  auto bad_vertex = link_program("#version 330 core\nvoid main() { gl_Position = 1; }\n", kFragment, "test shader");
  ASSERT_FALSE(bad_vertex);
  EXPECT_NE(bad_vertex.error().message.find("vertex shader compilation failed"), std::string::npos)
      << bad_vertex.error().message;

  // Both stages compile, but the fragment stage has no main(): only the link can tell.
  auto unlinked =
      link_program(kVertex, "#version 330 core\nout vec4 c;\nvoid helper() { c = vec4(1.0); }\n", "test shader");
  ASSERT_FALSE(unlinked);
  EXPECT_NE(unlinked.error().message.find("test shader: link failed"), std::string::npos) << unlinked.error().message;
  EXPECT_EQ(glGetError(), static_cast<GLenum>(GL_NO_ERROR));
}

}  // namespace
}  // namespace vdrig::gl
