set(viewer_public_deps vdrig::fitting vdrig::core)
set(viewer_private_deps glfw OpenGL::GL glm::glm opencv_imgproc)
