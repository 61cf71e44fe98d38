set(probe_public_deps vdrig::core)
set(probe_private_deps opencv_imgproc)
