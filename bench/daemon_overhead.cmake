# bench_daemon_overhead: vdrigd's time per frame beyond the (simulated) hardware's own time.
if(TARGET vdrig_capture AND TARGET vdrig_sim)
  add_executable(bench_daemon_overhead ${CMAKE_CURRENT_LIST_DIR}/daemon_overhead.cpp)
  target_link_libraries(bench_daemon_overhead PRIVATE vdrig::capture vdrig::sim vdrig_options)
endif()
