# SH-LSOP / HSH fitting throughput on full parameter maps (prints its own figures; see bench/sh_fit.cpp).
add_executable(bench_sh_fit ${CMAKE_CURRENT_SOURCE_DIR}/sh_fit.cpp)
target_link_libraries(bench_sh_fit PRIVATE vdrig::fitting vdrig_options)
