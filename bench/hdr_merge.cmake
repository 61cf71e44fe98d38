# bench_hdr_merge: vdrig's HDR merge vs cv::MergeDebevec on the same synthetic bracket (speed and accuracy).
if(TARGET vdrig_calib)
  add_executable(bench_hdr_merge ${CMAKE_CURRENT_LIST_DIR}/hdr_merge.cpp)
  target_link_libraries(bench_hdr_merge PRIVATE vdrig::calib opencv_photo vdrig_options)
endif()
