# bench_results_table: the source method's comparison tests re-run on the simulator (issue #5); writes
# docs/results.md when given its path (`bench_results_table docs/results.md`), always prints the table.
if(TARGET vdrig_fitting AND TARGET vdrig_sim AND TARGET vdrig_rig AND TARGET vdrig_capture)
  add_executable(bench_results_table ${CMAKE_CURRENT_LIST_DIR}/results_table.cpp)
  target_link_libraries(bench_results_table PRIVATE vdrig::fitting vdrig::sim vdrig::rig vdrig::capture vdrig_options)
endif()
