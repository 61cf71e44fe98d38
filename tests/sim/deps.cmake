# sim tests: OpenCV's chessboard detector checks the simulated calibration target.
set(sim_test_deps opencv_calib3d opencv_imgproc)
