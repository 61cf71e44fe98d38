# bench_obsmap_build: seconds and peak RSS of streaming a 512x512-texel, 289-view observation map to a file.
if(TARGET vdrig_fitting AND TARGET vdrig_rig)
  add_executable(bench_obsmap_build ${CMAKE_CURRENT_LIST_DIR}/obsmap_build.cpp)
  target_link_libraries(bench_obsmap_build PRIVATE vdrig::fitting vdrig::rig vdrig_options)
endif()
