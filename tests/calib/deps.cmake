set(calib_test_deps opencv_imgproc opencv_imgcodecs opencv_calib3d vdrig::sim)
