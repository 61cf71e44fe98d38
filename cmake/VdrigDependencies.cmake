# Every dependency comes from Debian's packages (scripts/setup installs them).
find_package(Threads REQUIRED)
find_package(OpenCV REQUIRED COMPONENTS core imgproc imgcodecs calib3d photo)
find_package(Ceres REQUIRED)
find_package(Eigen3 REQUIRED NO_MODULE)
find_package(OpenEXR 3 REQUIRED)
find_package(Imath REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
find_package(CLI11 REQUIRED)
find_package(spdlog REQUIRED)
find_package(glfw3 3.3 REQUIRED)
find_package(glm REQUIRED)
find_package(OpenGL REQUIRED)
find_package(PkgConfig REQUIRED)
pkg_check_modules(ZSTD REQUIRED IMPORTED_TARGET libzstd)

if(VDRIG_BUILD_TESTS)
  find_package(GTest REQUIRED)
endif()
if(VDRIG_BUILD_BENCH)
  find_package(benchmark REQUIRED)
endif()

# The hardware backends' optional libraries are looked up with their backends, in rig/CMakeLists.txt.
