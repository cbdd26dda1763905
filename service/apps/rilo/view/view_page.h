#pragma once
// The page `rilo view` serves (view_page.html, compiled in by CMake).
#include <string_view>

namespace rilo::tool {

std::string_view viewPageHtml();

}  // namespace rilo::tool
