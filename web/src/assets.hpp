// The console's page, script and style, embedded at build time from web/assets/ (web/CMakeLists.txt generates the
// definition): the page needs no network beyond this server.
#pragma once

#include <string_view>
#include <vector>

namespace vdrig::web {

struct Asset {
  std::string_view name;  ///< the file's name in web/assets/ ("app.js")
  std::string_view text;
};

const std::vector<Asset>& assets();

}  // namespace vdrig::web
