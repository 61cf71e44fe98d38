# The capture tests drive the simulated rig.
set(capture_test_deps vdrig::sim)
