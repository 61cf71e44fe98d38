set(capture_public_deps vdrig::rig vdrig::core)
set(capture_private_deps opencv_imgcodecs)
