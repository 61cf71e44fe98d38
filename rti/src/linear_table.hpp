// Private to rti/: the table from 8- or 16-bit codes to fitted values that the importer and the stack fitter share.
#pragma once

#include <vector>

#include "vdrig/rti/import.hpp"

namespace vdrig::rti {

/// code -> value of channel c (R G B) for `bits`-bit images under `lin` (2^bits entries).
std::vector<float> linear_table(const Linearisation& lin, int bits, int channel);

}  // namespace vdrig::rti
