# bench_sim_render: seconds per simulated view of patchwork at 1024x768 (a 289-view capture, extrapolated from 24).
if(TARGET vdrig_sim)
  add_executable(bench_sim_render ${CMAKE_CURRENT_LIST_DIR}/sim_render.cpp)
  target_link_libraries(bench_sim_render PRIVATE vdrig::sim vdrig_options)
endif()
