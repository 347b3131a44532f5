#pragma once
// Text for HTML content and attribute values, shared by every page and chart of the report room.
// Pure; thread-safe.
#include <string>
#include <string_view>

namespace vtsim {

// < > & " ' as entities.
std::string html_escape(std::string_view s);

}  // namespace vtsim
