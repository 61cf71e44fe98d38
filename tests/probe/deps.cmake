# fitting's real-SH evaluation is the reference for probe's local band-0..2 basis (test_sh_irradiance).
set(probe_test_deps vdrig::fitting)
