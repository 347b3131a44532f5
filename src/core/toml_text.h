#pragma once
// TOML text parsed for vtsim's readers (config files, sweep specs): the nesting check first
// (check_toml_nesting: toml++ would overflow the stack on deep keys), then toml++, a syntax error
// as an InputError at path:line. Library-internal: toml++ is a private dependency of vtsim_lib.
#include <string>
#include <toml++/toml.h>

namespace vtsim {

// Refuses TOML text whose keys, inline tables and arrays nest more than 16 levels (toml++ would
// overflow the stack destroying them); InputError at path:line.
void check_toml_nesting(const std::string& text, const std::string& path);

toml::table parse_toml_text(const std::string& text, const std::string& path);

}  // namespace vtsim
