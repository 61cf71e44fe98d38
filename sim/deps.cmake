set(sim_public_deps vdrig::rig vdrig::core)
set(sim_private_deps opencv_imgproc)
