// The precompiled header of every vdrig library and executable (cmake/VdrigTargets.cmake, vdrig_use_pch;
// docs/build-time.md). Core's public headers include OpenCV's core, Eigen and spdlog, and most sources add
// nlohmann-json, so every object parsed them again: 2.5-3 s of a typical source's 9-11 s at -O3 (the rest is code
// generation, which no PCH saves). Only what every build has (the capture preset has no Ceres, OpenGL or GLFW) and
// what most sources include belongs here; a header that only a few sources use would cost every source its loading.
//
// A source must still include what it uses: the PCH is a build-time cache, not an include (a missing include shows
// with cmake -DVDRIG_PCH=OFF).
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <thread>
#include <utility>
#include <variant>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
