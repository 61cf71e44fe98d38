// Compiling and linking GLSL programs: the one place for the driver's error log, used by the viewer's renderers and
// by probe_gl's fusion shader.
#pragma once

#include <string>

#include "vdrig/core/result.hpp"

namespace vdrig::viewer {

/// Compiles both stages and links them into a program; returns its GL name (a GLuint). Needs a current OpenGL
/// context (GlContext). A stage that does not compile, or a program that does not link, is kInternal with `what`
/// ("fusion shader") and the driver's log; nothing stays allocated then. The caller deletes the program.
Result<unsigned> link_program(const std::string& vertex_source, const std::string& fragment_source,
                              const std::string& what);

}  // namespace vdrig::viewer
