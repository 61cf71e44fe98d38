set(fitting_public_deps vdrig::core)
set(fitting_private_deps Ceres::ceres opencv_imgproc PkgConfig::ZSTD)
