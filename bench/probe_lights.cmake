# bench_probe_lights: median cut (64, 256 lights) and SH-9 projection time on the real probes, and their E(n)
# accuracy against brute-force integration (prints a table; needs ../shared/data/probes).
if(TARGET vdrig_probe)
  add_executable(bench_probe_lights ${CMAKE_CURRENT_LIST_DIR}/probe_lights.cpp)
  target_link_libraries(bench_probe_lights PRIVATE vdrig::probe vdrig_options)
  target_compile_definitions(bench_probe_lights PRIVATE VDRIG_SHARED_DATA_DIR="${PROJECT_SOURCE_DIR}/../shared/data")
endif()
