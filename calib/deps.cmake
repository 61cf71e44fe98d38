set(calib_public_deps vdrig::rig vdrig::core)
set(calib_private_deps opencv_imgproc opencv_calib3d opencv_photo opencv_imgcodecs)
