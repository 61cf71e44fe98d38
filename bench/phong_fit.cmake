# Phong-1 whole-map fitting speed: 256 x 256 texels x 289 views on 2 threads (prints its own figures).
add_executable(bench_phong_fit ${CMAKE_CURRENT_SOURCE_DIR}/phong_fit.cpp)
target_link_libraries(bench_phong_fit PRIVATE vdrig::fitting vdrig_options)
