// The precompiled header of the test executables: every library's (common.hpp) and GoogleTest, which each of the
// 136 test sources includes (cmake/VdrigTargets.cmake; docs/build-time.md).
#pragma once

#include "vdrig_pch/common.hpp"

#include <gtest/gtest.h>
