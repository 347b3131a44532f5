// Quake 3 level entities (vtsim trace level-walk LEVEL): a .bsp's entity lump, a .pk3 (zip)
// holding one, or the entity text alone, chosen by the input's first bytes ("IBSP", "PK", other).
#include <cstdint>
#include <string>
#include <string_view>

#include "fuzz_targets.h"
#include "sim/view/q3_entities.h"

namespace vtsim::fuzz {

void q3_entities(const std::uint8_t* data, std::size_t size) {
  expect_accept_or_reject("q3_entities", [&] {
    const std::string_view bytes(reinterpret_cast<const char*>(data), size);
    Q3Limits limits;
    limits.max_entity_bytes = 1 << 20;
    limits.max_entities = 4096;
    if (bytes.starts_with("IBSP")) parse_q3_bsp(bytes, "fuzz.bsp", limits);
    else if (bytes.starts_with("PK")) read_q3_entities(input_file(data, size, "pk3"), limits);
    else parse_q3_entity_text(bytes, "fuzz entities", limits);
  });
}

}  // namespace vtsim::fuzz
