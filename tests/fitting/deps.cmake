set(fitting_test_deps vdrig::sim vdrig::rig vdrig::capture)
