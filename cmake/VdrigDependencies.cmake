# Every dependency comes from Debian's packages (scripts/setup installs them).
find_package(Threads REQUIRED)
# imgcodecs only for tests and benches, as an independent peer: vdrig's libraries and executables read and write
# images with libpng, libjpeg and libtiff (core/src/image_codec.cpp), since Debian's imgcodecs links GDAL, GDCM, HDF5,
# Poppler and ~100 more libraries, 0.15 s and 50 MB at every process start (issue #25).
find_package(OpenCV REQUIRED COMPONENTS core imgproc imgcodecs calib3d photo)
find_package(PNG REQUIRED)
find_package(JPEG REQUIRED)
find_package(TIFF REQUIRED)
find_package(Eigen3 REQUIRED NO_MODULE)
find_package(OpenEXR 3 REQUIRED)
find_package(Imath REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
find_package(CLI11 REQUIRED)
find_package(spdlog REQUIRED)
find_package(PkgConfig REQUIRED)
pkg_check_modules(ZSTD REQUIRED IMPORTED_TARGET libzstd)
# Switched off together with the modules that need them (VDRIG_WITH_CERES, VDRIG_WITH_GL; root CMakeLists.txt), so
# a capture-only build neither needs nor links them.
if(VDRIG_WITH_CERES)
  find_package(Ceres REQUIRED)
endif()
if(VDRIG_WITH_GL)
  find_package(glfw3 3.3 REQUIRED)
  find_package(glm REQUIRED)
  find_package(OpenGL REQUIRED)
endif()

if(VDRIG_BUILD_TESTS)
  find_package(GTest REQUIRED)
endif()
if(VDRIG_BUILD_BENCH)
  find_package(benchmark REQUIRED)
endif()

# The hardware backends' optional libraries are looked up with their backends, in rig/CMakeLists.txt.

# MPI (cluster/): optional. VDRIG_MPIEXEC_FLAGS is the one place the flags tests and bench_mpi give mpirun live:
# --oversubscribe (more ranks than the 2 cores here), --bind-to none (ranks run threads), the shared-memory and
# loopback transports only (containers have no usable high-speed network; vader's single-copy mechanism needs
# ptrace/CMA, often denied in containers) and plm_rsh_agent false (no ssh: a single node).
# As root (CI), mpirun also needs --allow-run-as-root, which the tests add when they run as root.
if(VDRIG_WITH_MPI)
  find_package(MPI COMPONENTS CXX)
  if(NOT MPI_CXX_FOUND)
    message(WARNING "VDRIG_WITH_MPI: no MPI found (install libopenmpi-dev, scripts/setup); building without MPI")
    set(VDRIG_WITH_MPI OFF CACHE BOOL "Build the MPI driver of cluster/ (vdrig fit/obsmap build --mpi)" FORCE)
  endif()
endif()
set(VDRIG_MPIEXEC_FLAGS "--oversubscribe;--bind-to;none;--mca;btl;self,vader;--mca;btl_vader_single_copy_mechanism;none;--mca;plm_rsh_agent;false"
    CACHE STRING "mpirun flags of the MPI tests and bench_mpi (a ;-list)")
