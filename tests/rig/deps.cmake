# rig tests see rig's private headers; test_modbus runs a libmodbus server of its own.
set(rig_test_deps vdrig_rig_internal)
if(VDRIG_WITH_MODBUS)
  list(APPEND rig_test_deps PkgConfig::MODBUS_PC)
endif()
